"""validation.number: what it refuses and the text of what is allowed.

The description of the allowed range is written only when a value is refused; every refusal must still
name the field, the value and the whole description, on each of its paths (not a number, a bool, an int
beyond the float range, NaN or infinity, below or at an open lower bound, above or at an open upper
bound), and a value inside is returned as a float.
"""

import math

import numpy as np
import pytest

from twinsense import validation as V
from twinsense.errors import ConfigError

CASES = [  # (value, keyword bounds, the allowed text expected)
    ("1", {}, "a finite number"),
    (True, {}, "a finite number"),
    (10**400, {}, "a finite number"),
    (math.nan, {"lo": 0.0}, "a finite number >= 0"),
    (-math.inf, {"hi": 2.0, "unit": "s"}, "a finite number <= 2 [s]"),
    (-1.0, {"lo": 0.0, "hi": 3.0}, "a finite number >= 0 and <= 3"),
    (0.0, {"lo": 0.0, "lo_open": True, "unit": "m"}, "a finite number > 0 [m]"),
    (3.5, {"lo": 0.0, "hi": 3.0}, "a finite number >= 0 and <= 3"),
    (3.0, {"hi": 3.0, "hi_open": True}, "a finite number < 3"),
]


@pytest.mark.parametrize("value, bounds, allowed", CASES)
def test_a_refused_value_names_field_value_and_the_allowed_range(value, bounds, allowed):
    with pytest.raises(ConfigError) as e:
        V.number("f.x", value, **bounds)
    assert e.value.field == "f.x" and e.value.allowed == allowed
    assert e.value.value is value


def test_values_inside_are_floats_and_times_use_the_same_rule():
    assert V.number("x", np.int64(3), lo=3) == 3.0 and type(V.number("x", 2)) is float
    assert V.time("t", 0.25) == 0.25
    with pytest.raises(ConfigError) as e:
        V.time("t", 2e10)
    assert e.value.allowed == f"a finite number >= {-V.TIME_MAX:g} and <= {V.TIME_MAX:g} [s]"
