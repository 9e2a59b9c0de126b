"""Default materials of robot links, from their names.

Structural links of industrial arms are cast or machined aluminium; grippers
and finger pads, covers and caps are plastic or rubber-like; sensor and camera
housings plastic. The first rule whose pattern occurs in the lower-case link
name wins; ``materials={link: name}`` overrides any link.
"""

from __future__ import annotations

import re

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.scene.materials import get_material

#: (regular expression on the lower-case link name, material name), first match wins.
LINK_MATERIAL_RULES: tuple[tuple[str, str], ...] = (
    (r"pad|tip|rubber|bumper", "silicone"),
    (r"finger|gripper|cover|cap|camera|sensor|skin", "plastic"),
    (r"", "aluminium"),
)


def default_material(link_name: str) -> str:
    name = link_name.lower()
    for pattern, material in LINK_MATERIAL_RULES:
        if re.search(pattern, name):
            return material
    return "aluminium"  # pragma: no cover - the last rule matches everything


def link_materials(link_names, overrides=None, field_name: str = "materials") -> dict[str, str]:
    """Material name of every link: the defaults, then ``overrides`` {link: material}."""
    out = {n: default_material(n) for n in link_names}
    if overrides is None:
        return out
    if not isinstance(overrides, dict):
        raise ConfigError(field_name, overrides, "a mapping {link name: material name}")
    for link, mat in overrides.items():
        if link not in out:
            raise UnknownNameError(f"{field_name}.link", link, list(out))
        try:
            get_material(mat)  # unknown material names list the library
        except UnknownNameError as e:  # named by the link it was given for, not only "material"
            raise UnknownNameError(f"{field_name}.{link}", mat, e.valid) from None
        out[link] = mat
    return out
