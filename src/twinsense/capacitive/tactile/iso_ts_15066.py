"""Permissible contact values of ISO/TS 15066:2016, Annex A, Table A.2 (a selection).

The biomechanical limits for power- and force-limited collaborative robots:
per body region, the maximum permissible pressure and force for
quasi-static contact (clamping, the body held against a fixed part); for
transient contact (the body free to recoil) the table allows twice those
values. The pressures are the 75th percentile of the pain-onset pressures
measured on 100 adults (University of Mainz study the specification cites);
the forces come from a literature survey of minor injuries. Values are per
body region (force) and per specific body area (pressure). Transient contact
with the skull, forehead and face is not permitted by the specification and
is marked as such here. The table is a guide for the risk assessment, not a
substitute for measurements per Annex A.
"""

from __future__ import annotations

from dataclasses import dataclass

from twinsense.errors import UnknownNameError

__all__ = ["BODY_REGIONS", "BodyRegionLimit", "ContactCheck", "check_contact", "limit"]

N_PER_CM2 = 1e4
"""1 N/cm^2 in Pa."""


@dataclass(frozen=True)
class BodyRegionLimit:
    """Permissible values of one body area.

    Attributes
    ----------
    region : str, the body region of the table (the force limit applies to it).
    area : str, the specific body area (the pressure limit applies to it).
    pressure_quasi_static : float [Pa]; force_quasi_static : float [N].
    transient_allowed : bool, False where the specification permits no transient contact.
    """

    region: str
    area: str
    pressure_quasi_static: float
    force_quasi_static: float
    transient_allowed: bool = True

    @property
    def pressure_transient(self) -> float:
        """Permissible transient pressure [Pa] (twice the quasi-static value; 0 where not permitted)."""
        return 2.0 * self.pressure_quasi_static if self.transient_allowed else 0.0

    @property
    def force_transient(self) -> float:
        """Permissible transient force [N] (twice the quasi-static value; 0 where not permitted)."""
        return 2.0 * self.force_quasi_static if self.transient_allowed else 0.0


def _row(region, area, p_n_cm2, force, transient=True):
    return BodyRegionLimit(region, area, p_n_cm2 * N_PER_CM2, float(force), transient)


BODY_REGIONS: dict[str, BodyRegionLimit] = {
    "forehead": _row("skull and forehead", "middle of forehead", 130, 130, transient=False),
    "chest_sternum": _row("chest", "sternum", 120, 140),
    "chest_pectoral": _row("chest", "pectoral muscle", 170, 140),
    "upper_arm_deltoid": _row("upper arms and elbow joints", "deltoid muscle", 190, 150),
    "forearm_muscle": _row("lower arms and wrist joints", "forearm muscle", 180, 160),
    "hand_palm": _row("hands and fingers", "palm (dominant hand)", 260, 140),
    "finger_pad": _row("hands and fingers", "forefinger pad (dominant hand)", 300, 140),
    "finger_end_joint": _row("hands and fingers", "forefinger end joint (dominant hand)", 280, 140),
    "back_of_hand": _row("hands and fingers", "back of the hand (dominant hand)", 200, 140),
    "thigh": _row("thighs and knees", "thigh muscle", 250, 220),
}
"""A selection of Table A.2 by a short key (pressures in Pa, forces in N)."""


def limit(key: str) -> BodyRegionLimit:
    """The permissible values of body area ``key`` (see :data:`BODY_REGIONS`)."""
    if key not in BODY_REGIONS:
        raise UnknownNameError("ISO/TS 15066 body area", key, list(BODY_REGIONS))
    return BODY_REGIONS[key]


@dataclass(frozen=True)
class ContactCheck:
    """A contact against the permissible values of a body area.

    Attributes
    ----------
    key : str; pressure : float [Pa]; force : float [N];
    pressure_ratio, force_ratio : float, the values over their limits;
    exceeded : bool, True when either ratio exceeds 1.
    """

    key: str
    pressure: float
    force: float
    pressure_ratio: float
    force_ratio: float
    exceeded: bool


def check_contact(key: str, pressure: float, force: float, transient: bool = False) -> ContactCheck:
    """Compare a contact's peak pressure [Pa] and force [N] with the limits of body area ``key``."""
    lim = limit(key)
    p_lim = lim.pressure_transient if transient else lim.pressure_quasi_static
    f_lim = lim.force_transient if transient else lim.force_quasi_static
    pr = float(pressure) / p_lim if p_lim > 0 else float("inf") if pressure > 0 else 0.0
    fr = float(force) / f_lim if f_lim > 0 else float("inf") if force > 0 else 0.0
    return ContactCheck(key, float(pressure), float(force), pr, fr, bool(pr > 1.0 or fr > 1.0))
