"""Screenshot of Rerun's web viewer showing a short twinsense run (docs/img/rerun-web-viewer.png).

Serves a run of the corridor example (depth camera, ToF camera, LiDAR, radar)
from a :class:`twinsense.stream.rerun.RerunSink` with the web viewer on
localhost, opens the page once in headless Chromium and keeps a screenshot.
A one-off documentation artefact, not a test.

Chromium's ``--screenshot`` fires before the viewer's WebAssembly has
compiled (``--virtual-time-budget`` does not wait for compilation), so the
page is driven over the DevTools protocol instead: navigate, wait a fixed
real time, capture. WebGL runs on the SwiftShader software rasteriser.

Usage::

    python tools/rerun_screenshot.py [--chromium /usr/bin/chromium] [--wait 30] [--out docs/img/rerun-web-viewer.png]
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import json
import socket
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

import websockets
import yaml

from twinsense.scenario import scenario_from_dict
from twinsense.simulate import simulate
from twinsense.stream.rerun import RerunSink

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-gl=angle", "--use-angle=swiftshader",
                  "--enable-unsafe-swiftshader", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--window-size=1280,800"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def scenario() -> dict:
    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d["duration"] = 0.4
    look = {"look_at": {"eye": [0.0, 0.0, 1.2], "target": [4.0, 0.0, 0.8]}}
    d["sensors"] += [
        {"name": "tof", "kind": "tof", "preset": "pmd_pico_flexx", "frame_rate": 5, "mount": {"pose": look}},
        {"name": "lidar", "kind": "lidar", "preset": "velodyne_vlp16", "frame_rate": 5,
         "mount": {"pose": {"position": [0.5, -1.5, 1.0]}}},
        {"name": "radar", "kind": "radar", "preset": "infineon_bgt60tr13c", "frame_rate": 5,
         "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.0], "target": [4.0, 0.0, 1.0]}}}},
    ]
    return d


async def capture(devtools_port: int, url: str, wait_s: float) -> bytes:
    """Open ``url`` in the browser's first tab, wait ``wait_s`` seconds, return a PNG of the page."""
    tabs = json.load(urllib.request.urlopen(f"http://127.0.0.1:{devtools_port}/json/list"))
    ws_url = next(t["webSocketDebuggerUrl"] for t in tabs if t["type"] == "page")
    async with websockets.connect(ws_url, max_size=None) as ws:
        ids = iter(range(1, 1_000_000))

        async def call(method: str, **params):
            mid = next(ids)
            await ws.send(json.dumps({"id": mid, "method": method, "params": params}))
            while True:  # skip events until our reply
                msg = json.loads(await ws.recv())
                if msg.get("id") == mid:
                    return msg.get("result", {})

        await call("Emulation.setDeviceMetricsOverride", width=1280, height=800, deviceScaleFactor=1, mobile=False)
        await call("Page.navigate", url=url)
        end = time.monotonic() + wait_s
        while time.monotonic() < end:  # drain events while the viewer loads and renders
            try:
                await asyncio.wait_for(ws.recv(), timeout=max(0.1, end - time.monotonic()))
            except TimeoutError:
                pass
        return base64.b64decode((await call("Page.captureScreenshot", format="png"))["data"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "rerun-web-viewer.png")
    ap.add_argument("--wait", type=float, default=30.0, help="seconds the page loads and renders before the capture")
    args = ap.parse_args()

    sc = scenario_from_dict(scenario(), base_dir=ROOT / "examples")
    sink = RerunSink(web_viewer=True, grpc_port=free_port(), web_port=free_port(), queue_size=1000)
    sink.open(sc.scene, sc.sensors)
    devtools = free_port()
    try:
        simulate(sc.scene, sc.sensors, sc.duration, on_frame=lambda s, f: sink.send(s, f.t, f), keep_frames=False)
        print(f"serving {sink.url}; web viewer {sink.web_url}")
        with tempfile.TemporaryDirectory() as profile:
            browser = subprocess.Popen([args.chromium, *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
                                        f"--remote-debugging-port={devtools}", "about:blank"],
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            try:
                for _ in range(200):  # until the DevTools endpoint answers
                    try:
                        urllib.request.urlopen(f"http://127.0.0.1:{devtools}/json/version")
                        break
                    except OSError:
                        time.sleep(0.1)
                png = asyncio.run(capture(devtools, sink.web_url, args.wait))
            finally:
                browser.terminate()
                browser.wait(30)
    finally:
        sink.close()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_bytes(png)
    print(f"wrote {args.out} ({len(png)} B)")


if __name__ == "__main__":
    main()
