"""What every frame provides, and the shared clock of sensor frame times.

A sensor (``name``, ``kind``, ``frame_rate`` [Hz], ``mount``,
``capture(scene, t, rng) -> Frame``, ``config_dict()``) reads the scene and
returns a frame; it never writes into the scene or keeps results.
``simulate`` and the recorder rely only on these members.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Frame(Protocol):
    """One sensor output at time ``t`` [s]."""

    t: float

    def streams(self) -> dict[str, np.ndarray]:
        """Arrays to record, one dataset per key (stacked over frames)."""
        ...


def frame_times(frame_rate: float, duration: float, t0: float = 0.0) -> np.ndarray:
    """Capture times [s] of a sensor at ``frame_rate`` [Hz] over ``[t0, t0 + duration)``.

    Computed as t0 + k / rate (no accumulated rounding), so sensors at related
    rates line up exactly on the shared clock.
    """
    n = int(np.floor(duration * frame_rate + 1e-9))
    n = max(n, 1)
    return t0 + np.arange(n) / frame_rate
