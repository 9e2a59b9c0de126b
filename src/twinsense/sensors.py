"""What every sensor and frame provides (structural interfaces).

A sensor reads the scene and returns a frame; it never writes into the scene
or keeps results. ``simulate`` and the recorder rely only on these members.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from twinsense.scene.scene import Mount, Scene


@runtime_checkable
class Frame(Protocol):
    """One sensor output at time ``t`` [s]."""

    t: float

    def streams(self) -> dict[str, np.ndarray]:
        """Arrays to record, one dataset per key (stacked over frames)."""
        ...


@runtime_checkable
class Sensor(Protocol):
    name: str
    kind: str
    frame_rate: float  # [Hz]
    mount: Mount

    def capture(self, scene: Scene, t: float, rng: np.random.Generator | None = None) -> Frame: ...

    def config_dict(self) -> dict[str, Any]: ...


def frame_times(frame_rate: float, duration: float, t0: float = 0.0) -> np.ndarray:
    """Capture times [s] of a sensor at ``frame_rate`` [Hz] over ``[t0, t0 + duration)``.

    Computed as t0 + k / rate (no accumulated rounding), so sensors at related
    rates line up exactly on the shared clock.
    """
    n = int(np.floor(duration * frame_rate + 1e-9))
    n = max(n, 1)
    return t0 + np.arange(n) / frame_rate
