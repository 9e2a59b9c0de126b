"""The Python examples of docs/robots.md run as written (in order, in a scratch directory)."""

import os
import re
from pathlib import Path

import h5py

DOC = Path(__file__).resolve().parents[2] / "docs" / "robots.md"


def test_robots_doc_examples_run(tmp_path):
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) == 3
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        namespace: dict = {}
        for block in blocks:
            exec(compile(block, str(DOC), "exec"), namespace)
    finally:
        os.chdir(cwd)
    assert "ur5/wrist_3_link" in {o.name for o in namespace["scene"].objects}
    # The co-simulation example records ToF and radar frames of the falling box.
    with h5py.File(tmp_path / "out" / "drop.h5") as f:
        assert {"tof", "radar"} <= set(f)
    assert namespace["result"].frame_counts["tof"] == 2
