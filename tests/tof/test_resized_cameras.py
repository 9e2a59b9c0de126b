"""Camera presets on another image size keep their optics: field of view and optical axis."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.depthcam import DepthCamera
from twinsense.presets import list_presets, make_sensor
from twinsense.render.rays import PinholeCamera
from twinsense.tof import PICO_FLEXX_MODES, tof_preset
from twinsense.tof.rendering import pinhole_for

SIZES = [(64, 48), (16, 12), (33, 25), (225, 171)]


def _camera_cases() -> list[tuple[str, str, dict]]:
    """(kind, preset, options) for every registered camera-like preset and pico flexx mode."""
    presets = list_presets()
    cases = [("camera", name, {}) for name in presets["camera"]]
    for name in presets["tof"]:
        if name == "pmd_pico_flexx":
            cases += [("tof", name, {"mode": m}) for m in PICO_FLEXX_MODES]
        else:
            cases.append(("tof", name, {}))
    return cases


CASES = _camera_cases()


def _pinhole(kind: str, preset: str, **options) -> PinholeCamera:
    if kind == "camera":
        return make_sensor(kind, preset, **options).config.camera
    return pinhole_for(tof_preset(preset, **options))


def _ray(cam: PinholeCamera, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit ray (..., 3) of ``cam`` through image coordinates (u, v) [px], from its own intrinsics."""
    x, y = cam.undistort(np.atleast_1d((u - cam.cx) / cam.fx).astype(float),
                         np.atleast_1d((v - cam.cy) / cam.fy).astype(float))
    d = np.stack([x, y, np.ones_like(x)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def test_every_camera_kind_is_covered():
    kinds = {k for k, _, _ in CASES}
    assert kinds == {"camera", "tof"}
    assert len(CASES) == len(list_presets()["camera"]) + len(list_presets()["tof"]) - 1 + len(PICO_FLEXX_MODES)


@pytest.mark.parametrize(("kind", "preset", "options"), CASES,
                         ids=[f"{k}-{o.get('mode', p)}" for k, p, o in CASES])
@pytest.mark.parametrize("size", SIZES, ids=[f"{w}x{h}" for w, h in SIZES])
def test_resized_camera_sees_the_same_field(kind, preset, options, size):
    """Every pixel of the resized image looks where the same image fraction of the preset looks.

    Pixel (r, c) of a W' x H' image covers the image fraction ((c + 0.5) / W', (r + 0.5) / H'),
    i.e. u = (c + 0.5) W / W' - 0.5 on the preset's own W x H image. Its ray, computed from the
    preset's own intrinsics, must be the resized camera's ray (float64 and the 1e-12 Newton
    inversion of the distortion: 1e-9). So the image edges (field of view) and the image
    centre (optical axis) stay where they were.
    """
    full = _pinhole(kind, preset, **options)
    w, h = size
    small = _pinhole(kind, preset, width=w, height=h, **options)
    assert (small.width, small.height) == (w, h)
    cc, rr = np.meshgrid(np.arange(w), np.arange(h))
    ref = _ray(full, (cc + 0.5) * full.width / w - 0.5, (rr + 0.5) * full.height / h - 0.5)
    np.testing.assert_allclose(small.directions(1), ref, atol=1e-9)
    # The principal point still projects the boresight, and the horizontal field of view
    # (between the outer edges of the middle row) is the preset's.
    np.testing.assert_allclose(small.project(np.array([[0.0, 0.0, 1.0]]))[0], (small.cx, small.cy), atol=1e-9)
    np.testing.assert_allclose(small.project(np.array([[0.0, 0.0, 1.0]]))[0],
                               ((full.cx + 0.5) * w / full.width - 0.5, (full.cy + 0.5) * h / full.height - 0.5),
                               atol=1e-9)

    def hfov(cam):
        v = np.array([(cam.height - 1) / 2.0])
        left, right = _ray(cam, np.array([-0.5]), v)[0], _ray(cam, np.array([cam.width - 0.5]), v)[0]
        return math.acos(float(np.clip(left @ right, -1, 1)))

    assert hfov(small) == pytest.approx(hfov(full), abs=1e-9)


def test_fov_presets_keep_their_nominal_field_of_view():
    # The paper's camera: 72 deg edge to edge at any width; the depth camera: 72 x 45 deg.
    for w in (16, 64, 225):
        cfg = tof_preset("paper_pico_flexx", width=w, height=w // 2 + 1)
        fx = cfg.camera_intrinsics[0]
        assert 2 * math.degrees(math.atan(w / 2 / fx)) == pytest.approx(72.0, abs=1e-9)
        cam = DepthCamera.preset("generic", width=w, height=w // 2 + 1).config.camera
        assert 2 * math.degrees(math.atan(w / 2 / cam.fx)) == pytest.approx(72.0, abs=1e-9)
        assert 2 * math.degrees(math.atan((w // 2 + 1) / 2 / cam.fy)) == pytest.approx(45.0, abs=1e-9)


def test_explicit_intrinsics_are_kept():
    cfg = tof_preset("pmd_pico_flexx", width=64, height=48, intrinsics_px=(60.0, 60.0, 10.0, 20.0))
    assert cfg.camera_intrinsics == (60.0, 60.0, 10.0, 20.0)
    cam = DepthCamera.preset("generic", width=64, height=48, cx=5.0, fx=30.0).config.camera
    assert (cam.fx, cam.cx) == (30.0, 5.0)
    # The other intrinsics still follow the new size.
    assert cam.cy == pytest.approx((85.0 + 0.5) * 48 / 171 - 0.5, abs=1e-12)
    # Same size: the preset's calibration unchanged.
    assert tof_preset("pmd_pico_flexx").camera_intrinsics == (213.08, 213.48, 106.31, 87.48)
