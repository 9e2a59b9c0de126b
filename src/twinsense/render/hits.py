"""Per-ray results of ray casting."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twinsense.errors import ConfigError


@dataclass(frozen=True, eq=False)
class Hits:
    """Closest hit of every ray (n rays, in the order they were given).

    A cast asked for only some fields (``cast(..., fields=...)``) leaves the
    others None; ``distance`` and ``object_id`` are always there.

    Attributes
    ----------
    distance : (n,) float64
        Distance from the ray origin along the unit direction [m]; inf on a miss.
    point : (n, 3) float64
        Hit point, world frame [m]; NaN on a miss.
    normal : (n, 3) float64
        Unit geometric normal, world frame, turned towards the side the ray
        came from; zeros on a miss.
    cos_incidence : (n,) float64
        Cosine of the angle between the ray and the normal, in [0, 1]; 0 on a miss.
    object_id : (n,) int32
        Index into ``scene.objects``; -1 on a miss.
    material_id : (n,) int32
        Index into ``scene.materials``; -1 on a miss.
    triangle_id : (n,) int32
        Triangle index within the object's mesh; -1 on a miss.
    velocity : (n, 3) float64
        World velocity of the hit surface point [m/s]; zeros on a miss.
    """

    distance: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    cos_incidence: np.ndarray
    object_id: np.ndarray
    material_id: np.ndarray
    triangle_id: np.ndarray
    velocity: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """(n,) bool: the ray hit something."""
        return self.object_id >= 0

    def __len__(self) -> int:
        return len(self.distance)

    def reshape(self, shape: tuple[int, ...]) -> Hits:
        """The same hits with the ray axis reshaped to ``shape`` (e.g. an image (H, W))."""
        def r(a):
            return None if a is None else a.reshape(*shape, *a.shape[1:])
        return Hits(*(r(getattr(self, f)) for f in self.__dataclass_fields__))


#: Every field a cast can compute, in Hits order.
HIT_FIELDS = ("distance", "point", "normal", "cos_incidence", "object_id", "material_id",
              "triangle_id", "velocity")
ALWAYS_FIELDS = frozenset({"distance", "object_id"})  # needed to tell hits from misses
_DTYPES = {"object_id": np.int32, "material_id": np.int32, "triangle_id": np.int32}
_SHAPES = {"point": 3, "normal": 3, "velocity": 3}


def check_fields(fields) -> frozenset:
    """The set of hit fields to compute: all for None, else ``fields`` checked against HIT_FIELDS."""
    if fields is None:
        return frozenset(HIT_FIELDS)
    want = frozenset(fields)
    bad = sorted(want - set(HIT_FIELDS))
    if bad:
        raise ConfigError("fields", bad, "names among: " + ", ".join(HIT_FIELDS))
    return want


def allocate_field(field: str, n: int) -> np.ndarray:
    """An uninitialised array for ``n`` rays of hit field ``field`` (dtype and shape as in Hits)."""
    k = _SHAPES.get(field)
    return np.empty((n, k) if k else n, dtype=_DTYPES.get(field, np.float64))


def field_array(field: str, n: int, buffers: dict | None = None) -> np.ndarray:
    """``buffers[field]`` if there is one (checked: the dtype and shape :func:`allocate_field`
    gives, C-contiguous, writeable), else a new array for ``n`` rays."""
    a = None if buffers is None else buffers.get(field)
    if a is None:
        return allocate_field(field, n)
    k = _SHAPES.get(field)
    shape = (n, k) if k else (n,)
    dtype = np.dtype(_DTYPES.get(field, np.float64))
    if (not isinstance(a, np.ndarray) or a.shape != shape or a.dtype != dtype
            or not a.flags.c_contiguous or not a.flags.writeable):
        raise ConfigError(f"buffers[{field!r}]", getattr(a, "shape", type(a).__name__),
                          f"a writeable C-contiguous {dtype} array of shape {shape}")
    return a
