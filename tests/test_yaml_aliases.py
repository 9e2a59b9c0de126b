"""YAML aliases: shared values are fine, aliases that multiply each other are refused quickly."""

import pytest
import yaml

from twinsense.scenario import MAX_YAML_NODES, ScenarioError, load_scenario, yaml_expanded_size


def test_expanded_size_counts_each_use_of_an_alias():
    data = yaml.safe_load("a: &a [1, 2]\nb: [*a, *a]\n")
    # top mapping 1 + keys 2 + a (1 + 2) + b (1 + 2 * 3) = 13
    assert yaml_expanded_size(data) == 13


def test_recursive_alias_counts_once_where_it_closes():
    data = yaml.safe_load("r: &r [1, *r]\n")
    # mapping 1 + key 1 + list (1 + scalar 1 + the list again, counted once) = 5
    assert yaml_expanded_size(data) == 5


def test_deep_nesting_does_not_exhaust_the_stack():
    data: list = []
    node = data
    for _ in range(100_000):
        node.append([])
        node = node[0]
    assert yaml_expanded_size(data) == 100_001


def test_billion_laughs_is_refused_naming_the_aliases(tmp_path):
    lines = ['a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for prev, name in zip("abcdefgh", "bcdefghi"):
        lines.append(f"{name}: &{name} [" + ", ".join([f"*{prev}"] * 9) + "]")
    path = tmp_path / "laughs.yaml"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    text = str(info.value)
    assert "(YAML aliases)" in text and str(MAX_YAML_NODES) in text and "billion laughs" in text
