"""Latency of the FMCW processing chain on one frame (one core).

Frame: 2 Rx x 16 chirps x 512 real samples (the BGT60TR13C dynamic mode of
the seed paper). Prints the median time per stage and for the whole chain
(range FFT, Doppler FFT, 2-D CFAR, peak grouping, angle estimation, point
cloud); the frame budget at 30 fps is 33 ms.

    .venv/bin/python benchmarks/bench_radar_processing.py
"""

from __future__ import annotations

import os

# One core, whatever the BLAS build would pick.
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import time  # noqa: E402

import numpy as np  # noqa: E402
from _timing import print_load_at_end, print_machine  # noqa: E402

from twinsense.radar.processing import (  # noqa: E402
    ProcessingSettings,
    cfar_2d,
    doppler_fft,
    estimate_direction_cosine,
    process_cube,
    range_fft,
    remove_dc,
)

C = 299_792_458.0
FS, N, M, T_C = 2e6, 512, 16, 300e-6
SLOPE = 6e9 / (N / FS)
FC = 58e9 + 3e9
LAM = C / FC


def frame(rng: np.random.Generator, n_rx: int = 2) -> np.ndarray:
    """(rx, chirp, sample) real IF: three point targets plus noise (12-bit-like scale)."""
    t = np.arange(N) / FS
    x = np.zeros((n_rx, M, N))
    for r, v, az in ((1.0, 0.5, 0.2), (2.3, -1.0, -0.4), (4.0, 2.0, 0.0)):
        for m in range(M):
            tau = 2 * (r + v * m * T_C) / C
            for a in range(n_rx):
                ph = 2 * np.pi * (58e9 * tau + SLOPE * tau * t) - np.pi * a * np.sin(az)
                x[a, m] += 100 * np.cos(ph)
    return 2048 + x + 30 * rng.standard_normal(x.shape)


def median_ms(fn, repeat: int = 300) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def main() -> None:
    rng = np.random.default_rng(0)
    cube = frame(rng)
    rx = np.arange(2) * LAM / 2
    args = dict(sample_rate=FS, slope=SLOPE, carrier_frequency=FC, chirp_repetition_time=T_C,
                rx_positions=rx)
    spec = range_fft(remove_dc(cube), window="hann")
    rd = doppler_fft(spec, window="hann")
    power = np.mean(np.abs(rd) ** 2, axis=0)
    snaps = rd[:, :3, :3].reshape(2, -1).T

    print_machine()
    print("one thread")
    print(f"frame: 2 rx x {M} chirps x {N} real samples; map {power.shape}")
    # Same-run anchor: the two bare NumPy FFTs of the same cube (real FFT over
    # the samples, complex FFT over the chirps), no windows, no CFAR.
    anchor_ms = median_ms(lambda: np.fft.fft(np.fft.rfft(cube, axis=-1), axis=1))
    print(f"  anchor: bare numpy rfft + fft of the same cube: {anchor_ms:7.3f} ms")
    stages = {
        "DC removal + range FFT (hann)": lambda: range_fft(remove_dc(cube), window="hann"),
        "Doppler FFT (hann)": lambda: doppler_fft(spec, window="hann"),
        "2-D CA-CFAR (default ring, 132 cells)": lambda: cfar_2d(power, "ca"),
        "2-D GO-CFAR": lambda: cfar_2d(power, "go"),
        "2-D OS-CFAR (default ring, rank filter)": lambda: cfar_2d(power, "os"),
        "2-D OS-CFAR, ring (1,1)/(2,4): 68 cells": lambda: cfar_2d(power, "os", guard=(1, 1),
                                                                train=(2, 4)),
        "monopulse, 9 detections": lambda: estimate_direction_cosine(snaps, rx, LAM, "monopulse"),
    }
    for name, fn in stages.items():
        print(f"  {name:40s} {median_ms(fn):7.3f} ms")
    for cf in ("ca", "os"):
        res = process_cube(cube, settings=ProcessingSettings(cfar=cf), **args)
        ms = median_ms(lambda cf=cf: process_cube(cube, settings=ProcessingSettings(cfar=cf),
                                                  **args))
        print(f"whole chain, {cf.upper()}-CFAR: {ms:7.3f} ms per frame "
              f"({len(res.detections)} detections); budget 33 ms at 30 fps; "
              f"chain / anchor = {ms / anchor_ms:.1f}")

    # 4 Rx x 3 Tx TDM-MIMO, complex IF, 96 chirps x 256 samples, Bartlett on 12 elements.
    n_tx, n_rx = 3, 4
    z = (rng.standard_normal((n_rx, 96, 256)) + 1j * rng.standard_normal((n_rx, 96, 256)))
    t = np.arange(256) / 10e6
    z += 3 * np.exp(2j * np.pi * 2e6 * t) * np.exp(-1j * np.pi * 0.3 * np.arange(n_rx))[:, None,
                                                                                      None]
    mimo_args = dict(sample_rate=10e6, slope=70e12, carrier_frequency=77e9,
                     chirp_repetition_time=100e-6,
                     rx_positions=np.arange(n_rx) * C / 77e9 / 2,
                     tx_positions=np.arange(n_tx) * 2 * C / 77e9)
    ms = median_ms(lambda: process_cube(z, **mimo_args), repeat=50)
    print(f"TDM-MIMO 3 Tx x 4 Rx x 96 chirps x 256 complex samples, Bartlett: {ms:7.3f} ms")
    print_load_at_end()


if __name__ == "__main__":
    main()
