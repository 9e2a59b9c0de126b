"""Embree 4 through ctypes: triangle scenes, instances and packet casts.

embreex's Python API casts single rays against one flat scene. The Embree 4
library it ships (``embreex.libs/libembree4-*.so.4``) can do more: one BVH
per moving object, built once in the object's frame, instanced in a small
top-level scene whose transforms are set every frame, so one traversal per
ray finds the closest hit over static and moving objects alike; and packets
of 8 rays (``rtcIntersect8``) traced together. This module binds the few
functions that needs; :mod:`twinsense.render.embree4_kernels` calls the
intersect functions from compiled loops without the GIL.

Every Embree handle is owned by a Python object whose finaliser releases it;
a scene holds its device, an instance scene the scenes it instances. Vertex
and index data are copied into buffers Embree allocates (nothing of ours has
to outlive a call). If the library cannot be found or loaded, :func:`library`
is None and the caller keeps to embreex.
"""

from __future__ import annotations

import ctypes
import glob
import importlib.util
import os
import weakref
from functools import lru_cache

import numpy as np

from twinsense.errors import ConfigError
from twinsense.forksafe import ForkSafeLock, cleared_in_child

# Enumerations of embree4/rtcore_common.h, rtcore_device.h, rtcore_geometry.h.
RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_GEOMETRY_TYPE_INSTANCE = 121
RTC_BUFFER_TYPE_INDEX = 0
RTC_BUFFER_TYPE_VERTEX = 1
RTC_FORMAT_UINT3 = 0x5003
RTC_FORMAT_FLOAT3 = 0x9003
RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR = 0x9234
RTC_BUILD_QUALITY_LOW = 0
RTC_BUILD_QUALITY_MEDIUM = 1
RTC_BUILD_QUALITY_HIGH = 2
RTC_DEVICE_PROPERTY_VERSION = 0
RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED = 32
RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED = 33
RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED = 34
RTC_INVALID_GEOMETRY_ID = 0xFFFFFFFF

# Layouts of embree4/rtcore_ray.h (checked against embreex's rtcore_ray.pxd and by
# tests/render/test_embree4.py with rays of known hits). RTCRayHit (one ray): RTCRay, 12
# four-byte fields (org xyz, tnear, dir xyz, time, tfar, mask, id, flags: 48 bytes,
# 16-byte aligned), then RTCHit: Ng xyz, u, v, primID, geomID,
# instID[RTC_MAX_INSTANCE_LEVEL_COUNT] (and, in builds with instance arrays,
# instPrimID[...]). RTCRayHit8: the same fields as arrays of 8 (structure of arrays,
# 32-byte aligned). Field f is word f of an RTCRayHit and words 8 f .. 8 f + 7 of an
# RTCRayHit8 (one per ray of the packet). The fields' numbers:
F_ORG = 0  # org_x, org_y, org_z: 0, 1, 2
F_TNEAR = 3
F_DIR = 4  # dir_x, dir_y, dir_z: 4, 5, 6
F_TIME = 7
F_TFAR = 8
F_MASK = 9
F_ID = 10
F_FLAGS = 11
F_PRIM = 17  # after Ng xyz (12-14), u, v (15, 16)
F_GEOM = 18
F_INST = 19  # instID[0]
#: Four-byte words allocated per RTCRayHit: 96 bytes of struct (instID and instPrimID
#: at one level each) plus slack for builds with more instance levels.
RAY1_WORDS = 64
#: Four-byte words allocated per RTCRayHit8 (21 fields x 8 = 168 words used with one
#: instance level; slack for more levels and optional fields).
RAY8_WORDS = 512
ALIGN = 64  # bytes: the buffers' start (Embree needs 16 for RTCRayHit, 32 for RTCRayHit8)


def _library_path() -> str | None:
    """The Embree 4 shared library that the installed embreex wheel bundles, or None."""
    spec = importlib.util.find_spec("embreex")
    if spec is None or not spec.submodule_search_locations:
        return None
    for loc in spec.submodule_search_locations:
        libs = os.path.join(os.path.dirname(os.path.abspath(loc)), "embreex.libs")
        found = sorted(glob.glob(os.path.join(libs, "libembree4*.so*")))
        if found:
            return found[0]
    return None


class _Lib:
    """The bound functions of one loaded library (argument and result types set)."""

    def __init__(self, path: str):
        lib = ctypes.CDLL(path)
        self.path = path
        vp, u32, sz = ctypes.c_void_p, ctypes.c_uint32, ctypes.c_size_t

        def fn(name, res, *args):
            f = getattr(lib, name)
            f.restype, f.argtypes = res, list(args)
            return f

        self.rtcNewDevice = fn("rtcNewDevice", vp, ctypes.c_char_p)
        self.rtcReleaseDevice = fn("rtcReleaseDevice", None, vp)
        self.rtcGetDeviceError = fn("rtcGetDeviceError", ctypes.c_int, vp)
        self.rtcGetDeviceLastErrorMessage = fn("rtcGetDeviceLastErrorMessage", ctypes.c_char_p, vp)
        self.rtcGetDeviceProperty = fn("rtcGetDeviceProperty", ctypes.c_ssize_t, vp, ctypes.c_int)
        self.rtcNewScene = fn("rtcNewScene", vp, vp)
        self.rtcReleaseScene = fn("rtcReleaseScene", None, vp)
        self.rtcCommitScene = fn("rtcCommitScene", None, vp)
        self.rtcSetSceneBuildQuality = fn("rtcSetSceneBuildQuality", None, vp, ctypes.c_int)
        self.rtcSetGeometryBuildQuality = fn("rtcSetGeometryBuildQuality", None, vp, ctypes.c_int)
        self.rtcNewGeometry = fn("rtcNewGeometry", vp, vp, ctypes.c_int)
        self.rtcReleaseGeometry = fn("rtcReleaseGeometry", None, vp)
        self.rtcCommitGeometry = fn("rtcCommitGeometry", None, vp)
        self.rtcAttachGeometry = fn("rtcAttachGeometry", u32, vp, vp)
        self.rtcSetNewGeometryBuffer = fn("rtcSetNewGeometryBuffer", vp, vp, ctypes.c_int, u32,
                                          ctypes.c_int, sz, sz)
        self.rtcSetGeometryInstancedScene = fn("rtcSetGeometryInstancedScene", None, vp, vp)
        self.rtcSetGeometryTimeStepCount = fn("rtcSetGeometryTimeStepCount", None, vp, u32)
        self.rtcSetGeometryTransform = fn("rtcSetGeometryTransform", None, vp, u32, ctypes.c_int, vp)
        # The casts take pointers as plain integers (size_t): the compiled loops
        # pass addresses they compute (arr.ctypes.data), and on x86-64 and
        # aarch64 a pointer and a size_t are passed alike.
        self.rtcIntersect1 = fn("rtcIntersect1", None, sz, sz, sz)
        self.rtcIntersect8 = fn("rtcIntersect8", None, sz, sz, sz, sz)


@lru_cache(maxsize=1)
def library() -> _Lib | None:
    """The loaded Embree 4 library, or None if it is not there or does not load
    (then backend "embree" uses embreex, as backend "embreex")."""
    path = _library_path()
    if path is None:
        return None
    try:
        return _Lib(path)
    except (OSError, AttributeError):
        return None


class Device:
    """An Embree device (one per process: :func:`device`)."""

    def __init__(self, lib: _Lib):
        self.lib = lib
        self.handle = lib.rtcNewDevice(None)
        if not self.handle:
            raise RuntimeError("Embree 4: rtcNewDevice failed")
        self._finalizer = weakref.finalize(self, lib.rtcReleaseDevice, self.handle)
        #: rtcIntersect8 is there natively (AVX, AVX2): packets of 8 rays.
        self.packet8 = bool(lib.rtcGetDeviceProperty(self.handle, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED))
        self.version = int(lib.rtcGetDeviceProperty(self.handle, RTC_DEVICE_PROPERTY_VERSION))

    def check(self, what: str) -> None:
        """Raise if the last call on this device failed (Embree records the first error)."""
        code = self.lib.rtcGetDeviceError(self.handle)
        if code:
            msg = self.lib.rtcGetDeviceLastErrorMessage(self.handle) or b""
            raise RuntimeError(f"Embree 4: {what} failed (error {code}: {msg.decode(errors='replace')})")


# A forked child inherits the device but not its task threads: a scene it builds gets a
# device of its own (the list starts empty there; scenes inherited from the parent keep
# theirs, which hold their device). The lock is free there even if another thread was
# making the device at the fork.
_DEVICE: list[Device] = cleared_in_child([])
_DEVICE_LOCK = ForkSafeLock()


def device() -> Device | None:
    """The process's Embree 4 device (created on first use), or None without the library."""
    lib = library()
    if lib is None:
        return None
    with _DEVICE_LOCK:
        if not _DEVICE:
            _DEVICE.append(Device(lib))
        return _DEVICE[0]


class TriangleScene:
    """A committed Embree scene of one triangle geometry (geomID 0; primID = row of ``faces``).

    vertices (n, 3) float [m], faces (m, 3) int: copied into Embree's own buffers
    as float32 and uint32.
    """

    def __init__(self, dev: Device, vertices: np.ndarray, faces: np.ndarray,
                 quality: int = RTC_BUILD_QUALITY_MEDIUM):
        lib = dev.lib
        self.device = dev
        v, f = _checked_mesh(vertices, faces)
        self.n_triangles = len(f)
        self.handle = _new(lib.rtcNewScene(dev.handle), dev, "rtcNewScene")
        self._finalizer = weakref.finalize(self, lib.rtcReleaseScene, self.handle)
        lib.rtcSetSceneBuildQuality(self.handle, quality)
        geom = _new(lib.rtcNewGeometry(dev.handle, RTC_GEOMETRY_TYPE_TRIANGLE), dev, "rtcNewGeometry")
        try:
            lib.rtcSetGeometryBuildQuality(geom, quality)
            # Embree reads vertices with 16-byte loads: its buffers come padded.
            vbuf = lib.rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, len(v))
            ibuf = lib.rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, len(f))
            dev.check("rtcSetNewGeometryBuffer")
            if (len(v) and not vbuf) or (len(f) and not ibuf):
                raise RuntimeError("Embree 4: rtcSetNewGeometryBuffer returned no buffer")
            if len(v):
                ctypes.memmove(vbuf, v.ctypes.data, v.nbytes)
            if len(f):
                ctypes.memmove(ibuf, f.ctypes.data, f.nbytes)
            lib.rtcCommitGeometry(geom)
            lib.rtcAttachGeometry(self.handle, geom)
        finally:
            lib.rtcReleaseGeometry(geom)  # the scene holds its own reference
        lib.rtcCommitScene(self.handle)
        dev.check("building a triangle scene")


def _new(handle: int | None, dev: Device, what: str) -> int:
    """``handle`` from an Embree constructor, or RuntimeError if it gave NULL (out of memory)."""
    if not handle:
        dev.check(what)
        raise RuntimeError(f"Embree 4: {what} returned NULL")
    return handle


def _checked_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """vertices (n, 3) float32 and faces (m, 3) uint32, contiguous, as Embree's buffers take them.

    Embree skips a triangle with an index outside 0..n - 1 (a negative one would
    wrap to ~4e9 as uint32) or a vertex beyond +-COORD_MAX without a word: such
    faces, vertices that are not finite or out of range, and non-integer indices
    are a ConfigError here.
    """
    v64 = np.asarray(vertices, dtype=float)
    f_in = np.asarray(faces)
    if v64.ndim != 2 or v64.shape[1] != 3:
        raise ConfigError("mesh.vertices", f"shape {v64.shape}", "(n, 3) coordinates [m]")
    if f_in.ndim != 2 or f_in.shape[1] != 3 or (f_in.size and f_in.dtype.kind not in "iu"):
        raise ConfigError("mesh.faces", f"shape {f_in.shape}, dtype {f_in.dtype}", "(m, 3) integer vertex indices")
    ok = _in_range(v64)
    if not ok.all():
        bad = int(np.flatnonzero(~ok.all(axis=1))[0])
        raise ConfigError(f"mesh.vertices[{bad}]", v64[bad].tolist(),
                          f"finite coordinates within +-{COORD_MAX:g} m (Embree skips triangles beyond)")
    if f_in.size and (f_in.min() < 0 or f_in.max() >= len(v64)):
        raise ConfigError("mesh.faces", f"indices {f_in.min()}..{f_in.max()}", f"vertex indices in 0..{len(v64) - 1}")
    return np.ascontiguousarray(v64, dtype=np.float32), np.ascontiguousarray(f_in, dtype=np.uint32)


#: Embree's largest valid vertex or instance coordinate (its FLT_LARGE, 1.844e18 [m]): it
#: silently skips a triangle or an instance whose bounds reach beyond (measured: a triangle
#: at 1.8e18 is hit, at 1.9e18 not).
COORD_MAX = 1.844e18


def _in_range(x: np.ndarray) -> np.ndarray:
    """Element-wise: ``x`` is finite and within +-COORD_MAX (False for NaN and inf)."""
    return np.abs(x) < COORD_MAX


class InstanceScene:
    """A top-level scene of instances of :class:`TriangleScene` s (geomID k: ``scenes[k]``).

    :meth:`pose` sets every instance's transform (local -> world) and
    re-commits the top level: cheap for a few dozen instances.
    """

    def __init__(self, dev: Device, scenes: list[TriangleScene]):
        lib = dev.lib
        self.device = dev
        self.scenes = list(scenes)  # keeps the instanced scenes alive
        self.handle = _new(lib.rtcNewScene(dev.handle), dev, "rtcNewScene")
        self._finalizer = weakref.finalize(self, lib.rtcReleaseScene, self.handle)
        # A few dozen instances rebuilt every frame: the fast build is the better trade.
        lib.rtcSetSceneBuildQuality(self.handle, RTC_BUILD_QUALITY_LOW)
        self._geoms = []
        for k, s in enumerate(self.scenes):
            g = _new(lib.rtcNewGeometry(dev.handle, RTC_GEOMETRY_TYPE_INSTANCE), dev, "rtcNewGeometry")
            lib.rtcSetGeometryInstancedScene(g, s.handle)
            lib.rtcSetGeometryTimeStepCount(g, 1)
            gid = lib.rtcAttachGeometry(self.handle, g)
            if gid != k:
                raise RuntimeError(f"Embree 4: instance {k} attached as geometry {gid}")
            self._geoms.append(g)
            # The scene keeps a reference; ours is released with the scene's object.
            weakref.finalize(self, lib.rtcReleaseGeometry, g)
        dev.check("building an instance scene")
        #: The key of the poses last committed (see :meth:`pose`).
        self.posed: object = None

    def pose(self, transforms: np.ndarray, key: object = None) -> None:
        """Set instance k's transform to ``transforms[k]`` (3, 4) float (rotation | translation,
        local -> world) and commit. ``key`` (e.g. the time) is kept in :attr:`posed`."""
        lib = self.device.lib
        tr = np.asarray(transforms, dtype=float).reshape(len(self._geoms), 3, 4)
        ok = _in_range(tr)
        if not ok.all():
            # Embree would build the top level over NaN bounds: refused here (the caster
            # names the object; this is the last line of defence).
            bad = int(np.flatnonzero(~ok.all(axis=(1, 2)))[0])
            raise ConfigError(f"instances[{bad}].transform", tr[bad].tolist(),
                              f"a finite rotation | translation (3, 4) within +-{COORD_MAX:g} m")
        # Column-major 3 x 4: the four columns (3 rotation columns, translation) one after another.
        cols = np.ascontiguousarray(tr.transpose(0, 2, 1), dtype=np.float32)
        for k, g in enumerate(self._geoms):
            lib.rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, cols[k].ctypes.data)
            lib.rtcCommitGeometry(g)
        lib.rtcCommitScene(self.handle)
        self.device.check("posing the instances")
        self.posed = key
