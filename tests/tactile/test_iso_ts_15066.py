"""ISO/TS 15066 Table A.2 values and the limit check."""

import pytest

from twinsense.capacitive.tactile.iso_ts_15066 import BODY_REGIONS, check_contact, limit
from twinsense.errors import UnknownNameError


def test_table_values_as_published():
    # ISO/TS 15066:2016 Table A.2 (N/cm^2 -> Pa: x 1e4; forces in N).
    assert limit("hand_palm").pressure_quasi_static == pytest.approx(260e4, rel=0, abs=1e-6)
    assert limit("finger_pad").pressure_quasi_static == pytest.approx(300e4, rel=0, abs=1e-6)
    assert limit("hand_palm").force_quasi_static == 140.0
    assert limit("forearm_muscle").force_quasi_static == 160.0
    assert limit("chest_sternum").force_quasi_static == 140.0
    # Transient contact: twice the quasi-static values, none for the forehead.
    assert limit("hand_palm").force_transient == 280.0
    assert limit("forehead").force_transient == 0.0
    assert all(v.force_quasi_static > 0 and v.pressure_quasi_static > 0 for v in BODY_REGIONS.values())


def test_check_flags_a_contact_above_either_limit():
    ok = check_contact("hand_palm", 1e5, 10.0)
    assert not ok.exceeded and ok.force_ratio == pytest.approx(10 / 140, rel=1e-12, abs=0.0)
    assert check_contact("hand_palm", 3e6, 10.0).exceeded  # pressure above 260 N/cm^2
    assert check_contact("hand_palm", 1e5, 150.0).exceeded  # force above 140 N
    assert not check_contact("hand_palm", 1e5, 150.0, transient=True).exceeded
    assert check_contact("forehead", 1e3, 1.0, transient=True).exceeded
    with pytest.raises(UnknownNameError, match="hand_palm"):
        limit("elbow_tip")
