"""twinsense's errors survive pickling (they cross to the parent from capture processes and sweep workers)."""

import pickle

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.scenario import ScenarioError
from twinsense.simulate import CaptureProcessError


def test_errors_come_back_with_their_type_message_and_fields():
    for exc in (ConfigError("a.b", 1.5, "a number below 1", source="s.yaml"),
                UnknownNameError("material", "unobtainium", ["steel", "wood"]),
                ScenarioError("s.yaml", [("duration", -1, "a number > 0"), ("seed", "x", "an integer")]),
                CaptureProcessError("capture process 1 ended")):
        got = pickle.loads(pickle.dumps(exc, protocol=5))
        assert type(got) is type(exc) and str(got) == str(exc) and got.args == exc.args
        assert vars(got) == vars(exc)
    got = pickle.loads(pickle.dumps(UnknownNameError("material", "x", ["b", "a"])))
    assert got.valid == ("a", "b") and isinstance(got, KeyError) and str(got).startswith("material = 'x'")
