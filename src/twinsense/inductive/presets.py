"""Named inductive proximity sensors: cylindrical M12, M18 and M30, flush and non-flush.

Datasheet figures follow the Pepperl+Fuchs cylindrical family (EN IEC
60947-5-2 devices): rated operating distances s_n of 2 / 4 mm (M12 flush /
non-flush), 5 / 8 mm (M18) and 10 / 15 mm (M30); hysteresis typ. 5 %;
switching point drift within +-10 % over -25..70 deg C; repeat accuracy
0.3 mm at s_n = 6 mm (NEB6-12GM50-E1), i.e. 5 % of s_n; switching
frequencies 1000 Hz (NBB5-18GK50-E2, M18 flush) and 500 Hz (M18 non-flush,
NBN8-18GM50-E2), 150 Hz (NCN30 non-flush M30); the M12 (1500 / 1000 Hz) and
M30 flush (300 Hz) figures are the family's typical values.

What the makers do not publish is representative: oscillator frequencies
(500 kHz for M12, 700 kHz for M18, 400 kHz for M30, inside the usual
100 kHz - 1 MHz), the ferrite pot-core proportions (see ``head.py``), 100
turns (the amplitude depends on relative changes only, so the turn count cancels),
coil Q0 = 80, a nickel-plated brass sleeve 1 mm thick (1.5 mm for M30).
A non-flush sensor has the same core without its outer wall, a wider
winding and its sleeve set back behind the core.

The frequencies are chosen by the reduction factors, which fall as the
frequency rises (a plate's surface resistance grows as sqrt(f) towards
steel's): M18 and M30 run at the lowest round frequency at which direct
FEM solves at the switching threshold put the flush head's brass at 0.475
or less (catalogue range 0.35-0.5) and every other factor, flush and
non-flush, inside its catalogue range. M12 meets this at 500 kHz and would
drop copper below 0.15 at 1 MHz; its s_n is 0.44 core radii against 0.7-0.8
for M18 and M30, so a coil-radius-to-skin-depth scaling does not carry over
between sizes (docs/inductive.md, section 6).
"""

from __future__ import annotations

from collections.abc import Callable

from twinsense.errors import UnknownNameError
from twinsense.inductive.config import InductiveConfig
from twinsense.inductive.fem import MeshSpec
from twinsense.inductive.head import HeadGeometry

# (thread radius, sleeve wall, core radius) [m], oscillator frequency [Hz], (s_n flush, s_n non-flush) [m],
# (switching frequency flush, non-flush) [Hz]
_SIZES = {
    "m12": ((6e-3, 1.0e-3, 4.5e-3), 500e3, (2e-3, 4e-3), (1500.0, 1000.0)),
    "m18": ((9e-3, 1.0e-3, 7.0e-3), 700e3, (5e-3, 8e-3), (1000.0, 500.0)),
    "m30": ((15e-3, 1.5e-3, 12.5e-3), 400e3, (10e-3, 15e-3), (300.0, 150.0)),
}


def _make(size: str, flush: bool) -> Callable[[], InductiveConfig]:
    (rt, wall, rc), f, sns, fsw = _SIZES[size]
    k = 0 if flush else 1

    def build() -> InductiveConfig:
        head = HeadGeometry(rc, rt - wall, rt, shielded=flush)
        # Table resolution: cells of Rc / 18 in the winding, first cell half a skin depth inside a metal.
        mesh = MeshSpec(h_coil=rc / 18, skin_fraction=0.5, growth=1.3, domain=12.0)
        return InductiveConfig(head, f, sns[k], hysteresis=0.05, coil_q=80.0, frame_rate=fsw[k],
                               switching_frequency=fsw[k], repeatability=0.05, mesh=mesh)

    return build


#: Named configurations: name -> (config builder, description).
INDUCTIVE_PRESETS: dict[str, tuple[Callable[[], InductiveConfig], str]] = {}
for _size, (_, _f, _sns, _fsw) in _SIZES.items():
    for _flush, _label in ((True, "flush"), (False, "nonflush")):
        _k = 0 if _flush else 1
        INDUCTIVE_PRESETS[f"{_size}_{_label}"] = (
            _make(_size, _flush),
            f"{_size.upper()} inductive switch, {'flush (shielded)' if _flush else 'non-flush (unshielded)'}, "
            f"s_n = {_sns[_k] * 1e3:g} mm, {_f / 1e3:g} kHz oscillator, {_fsw[_k]:g} Hz switching")


def inductive_config(preset_name: str, **overrides) -> InductiveConfig:
    """The configuration of a named preset with fields replaced."""
    if preset_name not in INDUCTIVE_PRESETS:
        raise UnknownNameError("Inductive preset", preset_name, list(INDUCTIVE_PRESETS))
    cfg = INDUCTIVE_PRESETS[preset_name][0]()
    return cfg.with_overrides(**overrides) if overrides else cfg
