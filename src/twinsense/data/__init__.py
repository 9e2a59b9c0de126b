"""Real device recordings shipped with twinsense (package data).

Each recording sits in its own folder under ``twinsense/data/real/`` with its
README (source, commit, configuration, what was verified) and the licence of
its source (``LICENSE-source.txt``). They are used by the tests and the radar
demos and are installed with the package, so they work for a pip user too.

- ``bgt60tr13c_napas``: Infineon BGT60TR13C raw IF recording, ifxdaq layout,
  (256 frames, 3 rx, 8 chirps, 64 samples) uint16; MIT licence.
- ``iwr1843_dca1000``: TI IWR1843 one-frame DCA1000 capture with its mmWave
  ``.cfg``; Clear-BSD licence.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from twinsense.errors import UnknownNameError

_FOLDERS = {
    "bgt60tr13c_napas": "infineon-bgt60tr13c-napas/BGT60TR13C_record_napaszhar_220260106-151615",
    "iwr1843_dca1000": "ti-iwr1843-dca1000-oneframe",
}


def real_recording(name: str) -> Path:
    """Folder of the shipped real recording ``name`` (see the module docstring).

    Raises ``UnknownNameError`` (listing the names) for an unknown name and
    ``FileNotFoundError`` naming the path if the package data is missing
    (a broken installation).
    """
    if name not in _FOLDERS:
        raise UnknownNameError("real recording", name, list(_FOLDERS))
    path = Path(str(resources.files("twinsense.data"))) / "real" / _FOLDERS[name]
    if not path.is_dir():
        raise FileNotFoundError(f"twinsense's package data is missing: {path} (reinstall twinsense)")
    return path


def bgt60_radar_npy() -> Path:
    """The BGT60TR13C recording's ``radar.npy`` (256, 3, 8, 64) uint16."""
    return real_recording("bgt60tr13c_napas") / "RadarIfxAvian_00" / "radar.npy"


__all__ = ["bgt60_radar_npy", "real_recording"]
