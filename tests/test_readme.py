"""The README's Python examples run as written (in order, in a scratch directory)."""

import os
import re
from pathlib import Path

import trimesh

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_blocks_run(tmp_path):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) >= 4
    # The tour loads a part in millimetres.
    trimesh.creation.box(extents=(100, 80, 60)).export(tmp_path / "part.stl")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        namespace: dict = {}
        for block in blocks:
            exec(compile(block, str(README), "exec"), namespace)
    finally:
        os.chdir(cwd)
    assert (tmp_path / "out" / "run.h5").exists()
