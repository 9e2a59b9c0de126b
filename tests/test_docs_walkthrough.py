"""A new user's path through the README and docs: the people examples run as
written, the YAML fragment describes the same person as the Python one, and
every relative link and #anchor of the user docs resolves."""

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

import twinsense as ts
from twinsense.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[1]
USER_DOCS = ["README.md", "docs/robots.md", "docs/people.md", "docs/simulate.md",
             "docs/streaming.md", "docs/ros2-mcap.md"]


def _blocks(path: Path, lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", path.read_text(), flags=re.S | re.M)


def _alice_poses(scene, times) -> dict[str, np.ndarray]:
    return {o.name: np.stack([o.pose_at(t).matrix for t in times])
            for o in scene.objects if o.name.startswith("alice/")}


def test_people_doc_python_and_yaml_are_the_same_person():
    doc = ROOT / "docs" / "people.md"
    (py,) = _blocks(doc, "python")
    (fragment,) = _blocks(doc, "yaml")
    namespace: dict = {}
    exec(compile(py, str(doc), "exec"), namespace)
    data = yaml.safe_load(fragment)
    data.update(name="people_doc", duration=1.0, seed=0, sensors=[])
    scenario = scenario_from_dict(data, source=str(doc))
    # Standing, walking (start 0.5 s), arrived, reaching (6.0 s + 1.0 s) and holding.
    times = [0.0, 0.7, 1.5, 3.0, 6.5, 7.5]
    from_python = _alice_poses(namespace["scene"], times)
    from_yaml = _alice_poses(scenario.scene, times)
    assert len(from_python) > 10 and set(from_python) == set(from_yaml)
    # The text says the scenario takes "the same description": both build the
    # same Walk and Reach from the same numbers (the fragment spells out the
    # Python defaults duration 1.0 s and hold 1.0 s), so the poses agree to
    # float rounding of one evaluation: 1e-12 m (and 1e-12 in rotation entries).
    for name, m in from_python.items():
        np.testing.assert_allclose(from_yaml[name], m, rtol=0, atol=1e-12, err_msg=name)
    # Bob, the Walker of the Python block, is in the scene as "bob/<link>".
    assert any(o.name.startswith("bob/") for o in namespace["scene"].objects)


def test_readme_people_snippets_run():
    text = (ROOT / "README.md").read_text()
    # The inline call of the People section, then its block.
    (inline,) = re.findall(r"^`(add_person\(scene, \"alice\".*?)`$", text, flags=re.M)
    (block,) = re.findall(r"^```\n(from twinsense\.scene\.human import .*?)^```", text, flags=re.S | re.M)
    namespace: dict = {"scene": ts.Scene()}
    exec(compile(block + inline + "\n", "README.md", "exec"), namespace)
    names = {o.name for o in namespace["scene"].objects}
    # "one object per link (`"alice/left_foot"`)"
    assert "alice/left_foot" in names
    assert any(n.startswith("bob/") for n in names) and any(n.startswith("carol/") for n in names)


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation but - and _ dropped, spaces to -."""
    s = heading.strip().lower().replace("`", "")
    return re.sub(r"[^\w\- ]", "", s).replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    out, fenced = set(), False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and line.startswith("#"):
            out.add(_slug(line.lstrip("#")))
    return out


def test_slug_matches_github():
    # Headings of these docs and the anchors GitHub gives them (as linked from the README).
    assert _slug("The whole cell on two cores: where a scene second goes") == \
        "the-whole-cell-on-two-cores-where-a-scene-second-goes"
    assert _slug("The moving radar's render, compiled") == "the-moving-radars-render-compiled"
    assert _slug("Kinematic trees (`twinsense.scene.articulated`)") == "kinematic-trees-twinsensescenearticulated"


@pytest.mark.parametrize("doc", USER_DOCS)
def test_user_doc_links_resolve(doc):
    path = ROOT / doc
    text = path.read_text()
    broken = []
    for m in re.finditer(r"\]\(([^)\s]+)\)", text):
        link = m.group(1)
        if re.match(r"[a-z]+:", link):
            continue
        target, _, anchor = link.partition("#")
        dest = (path.parent / target) if target else path
        line = text[:m.start()].count("\n") + 1
        if not dest.exists():
            broken.append(f"{doc}:{line}: {link} (no such file)")
        elif anchor and dest.is_file() and anchor not in _anchors(dest):
            broken.append(f"{doc}:{line}: {link} (no such heading)")
    assert not broken, "\n".join(broken)


def test_readme_point_cloud_export_commands_run(tmp_path):
    """The README's `twinsense run` + `twinsense export` lines of the Rerun and
    point-cloud block, as written, from a folder holding `examples/`."""
    import subprocess
    import sys

    import h5py

    text = (ROOT / "README.md").read_text()
    (block,) = [b for b in _blocks(ROOT / "README.md", "bash") if "twinsense export" in b]
    lines = [ln.split("#")[0].split() for ln in block.splitlines()
             if ln.startswith(("twinsense run", "twinsense export"))]
    assert [ln[1] for ln in lines] == ["run", "export"]
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    exe = Path(sys.executable).with_name("twinsense")
    for ln in lines:
        r = subprocess.run([str(exe), *ln[1:]], capture_output=True, text=True, cwd=tmp_path, timeout=300)
        assert r.returncode == 0, f"{' '.join(ln)}: {r.stderr}"
    recording, pcd = tmp_path / lines[1][2], tmp_path / lines[1][3]
    frame = int(lines[1][lines[1].index("--frame") + 1])
    header = pcd.read_bytes().split(b"DATA")[0].decode()
    # One point per valid pixel (depth > 0, 0 marks invalid) of that frame, exactly.
    with h5py.File(recording) as f:
        valid = int((f["tof"]["depth"][frame] > 0).sum())
    assert valid > 1000 and f"POINTS {valid}\n" in header
    assert "VERSION 0.7" in header and text.count("PCD v0.7") == 1


def test_people_doc_gait_table_is_boulics_closed_form():
    """docs/people.md's table for H = 1.75 m against Boulic et al. (1990):
    H_t = 0.530 H, RV = v / H_t, D_c = 1.346 / sqrt(RV), stride v D_c,
    cadence 120 / D_c, D_s / D_c = 0.752 - 0.143 / D_c; and GaitTiming gives the same."""
    from twinsense.scene.gait import GaitTiming

    text = (ROOT / "docs" / "people.md").read_text()
    assert "For H = 1.75 m:" in text
    rows = re.findall(r"^\| (\d\.\d) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \|$", text, flags=re.M)
    assert len(rows) == 4
    h_t = 0.530 * 1.75
    for row in rows:
        v, rv, d_c, stride, cadence, duty = map(float, row)
        exact_d_c = 1.346 / np.sqrt(v / h_t)
        expected = (v / h_t, exact_d_c, v * exact_d_c, 120.0 / exact_d_c, 0.752 - 0.143 / exact_d_c)
        # The table rounds to 3 decimals (1 for the cadence): half a unit of the last place.
        for shown, exact, half_ulp in zip((rv, d_c, stride, cadence, duty), expected,
                                          (5e-4, 5e-4, 5e-4, 0.05, 5e-4)):
            assert abs(shown - exact) <= half_ulp + 1e-12, (v, shown, exact)
        g = GaitTiming(v, h_t)
        got = (g.relative_velocity, g.cycle_duration, g.stride_length, g.cadence, g.relative_support)
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=0)


def test_robots_doc_scenario_fragment_is_the_python_robot():
    """docs/robots.md's `robots:` fragment builds as written (plus a name and a
    duration), and is the robot its Python API builds from the same numbers."""
    from twinsense.robots import load_robot
    from twinsense.scene import JointKeyframes

    doc = ROOT / "docs" / "robots.md"
    (fragment,) = [b for b in _blocks(doc, "yaml") if b.startswith("robots:")]
    data = yaml.safe_load(fragment)
    data.update(name="robots_doc", duration=2.0)
    scenario = scenario_from_dict(data, source=str(doc))
    entry = data["robots"][0]
    keyframes = entry["joints"]["keyframes"]
    robot = load_robot("ur5", joints=JointKeyframes(keyframes["times"], keyframes["values"]),
                       base=ts.Pose(tuple(entry["base"]["position"])), materials=entry["materials"])
    scene = ts.Scene()
    scene.add_articulated(robot)
    (wrist,) = scenario.sensors
    tool0 = ts.Mount(ts.Pose(), parent="ur5/tool0")   # the flange frame, which has no geometry
    for t in (0.0, 0.4, 1.0, 1.7):
        flange = tool0.pose_at(scene, t).matrix
        built = tool0.pose_at(scenario.scene, t).matrix
        # Same kinematics from the same numbers: equal to float rounding (1e-12 m).
        np.testing.assert_allclose(built, flange, rtol=0, atol=1e-12)
        # "mount: {parent: ur5/tool0, pose: {position: [0, 0, 0.02]}}": 2 cm along the flange's z.
        sensor = wrist.mount.pose_at(scenario.scene, t).matrix
        np.testing.assert_allclose(sensor[:3, 3], flange[:3, 3] + 0.02 * flange[:3, 2], rtol=0, atol=1e-12)
    assert next(o for o in scenario.scene.objects if o.name == "ur5/base_link").material.name == "mild_steel"
