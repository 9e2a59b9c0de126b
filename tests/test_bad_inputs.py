"""Every malformed input in the catalogue (benchmarks/bad_inputs.py) gives a
twinsense error that names the field: the scenario path, the API field or the file.

The catalogue covers scenario dicts and files, constructors and calls of the
public API, mesh files and recordings; ``python benchmarks/bad_inputs.py``
prints the same result as a summary.
"""

import importlib.util
import sys
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "bad_inputs.py"
_spec = importlib.util.spec_from_file_location("twinsense_bad_inputs", _PATH)
bad_inputs = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = bad_inputs  # its dataclass looks its module up while it is defined
_spec.loader.exec_module(bad_inputs)

CASES = bad_inputs.catalogue()


def test_catalogue_size_and_unique_ids():
    # At least 500 distinct malformed inputs, each reported under its own id.
    assert len(CASES) >= 500
    assert len({c.id for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_gives_a_clear_error(case, tmp_path):
    outcome, msg = bad_inputs.run_case(case, tmp_path)
    assert outcome == "clear", f"{outcome}: expected a twinsense error naming {case.field!r}, got {msg!r}"


@pytest.mark.parametrize("content", [
    bytes(range(256)),  # binary
    b"name: x\nname: y\n",  # duplicate key
    b"duration: .nan\n",
    b"objects: [{name: a, geometry: {type: sphere, radius: 1.0e-300}}]\n",
    b"objects: [{name: a, geometry: {type: box, size: [1, 1, 1]}, pose: {quat_xyzw: [1.0e+200, 1e200, 0, 0]},"
    b" motion: {type: waypoints, points: [[0, 0, 0], [0, 0, 0]], speed: 1}}]\n",
])
def test_cli_reports_bad_files_without_traceback(content, tmp_path):
    # The command line prints the twinsense error (file, field, value, what is allowed) and exits with 2.
    from typer.testing import CliRunner

    from twinsense.cli import app

    p = tmp_path / "bad.yaml"
    p.write_bytes(content)
    res = CliRunner().invoke(app, ["validate", str(p)])
    assert res.exit_code == 2, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)
    assert "Traceback" not in res.output and "bad.yaml: 1 problem" in res.output
