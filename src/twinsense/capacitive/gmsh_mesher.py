"""Optional unstructured mesher: gmsh (GPL, an optional extra).

Selected with ``MeshSettings(mesher="gmsh")``. The sensing box, the substrate
slab and every planar electrode are built as OpenCASCADE entities and
fragmented together, so the tetrahedral mesh is conforming to the substrate
interfaces and has every electrode polygon as an embedded surface: curved or
slanted outlines (rings, disks, custom polygons) are then followed exactly
instead of by the staircase of the default grid. The cell size grows from
``h_min`` at the electrode outlines (where the field is singular) with the
same linear law as the grid mesher, ``min(h_max, h_min + (growth - 1) d)``
(a distance field and a threshold field), and is at most ``h_refine`` inside
the refine boxes. Tetrahedra come from HXT (gmsh's Frontal 3-D algorithm
drops embedded surfaces).

gmsh is imported only inside :func:`gmsh_layout_mesh`; without it, using this
mesher raises ImportError with the install hint. gmsh is a process-wide
singleton: a lock serialises builds, a session started here is finalised here,
and a session the caller already had is left running with its options
restored. Solid electrodes (closed bodies) are not embedded as surfaces; the
mesh is refined to ``h_min`` over their bounding box and their nodes are
found by the inside test, as on the grid.
"""

from __future__ import annotations

import ctypes
import math
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from twinsense.capacitive.layouts import Electrode
from twinsense.capacitive.mesh import SimplexMesh, _oriented, cached_mesh

__all__ = ["GMSH_INSTALL_HINT", "gmsh_layout_mesh", "gmsh_version"]

GMSH_INSTALL_HINT = "pip install 'twinsense[gmsh]'"

_LOCK = threading.Lock()

# Quiet, reproducible, sizes from the background field only.
_OPTIONS = {
    "General.Terminal": 0,
    "General.Verbosity": 1,
    "General.NumThreads": 1,  # one thread: the same mesh on every run (cache)
    "Mesh.Algorithm": 6,  # Frontal-Delaunay for the surfaces
    "Mesh.Algorithm3D": 10,  # HXT keeps embedded surfaces
    "Mesh.MeshSizeExtendFromBoundary": 0,
    "Mesh.MeshSizeFromPoints": 0,
    "Mesh.MeshSizeFromCurvature": 0,
    "Mesh.Optimize": 1,
}


def _import_gmsh():
    try:
        import gmsh
    except (ImportError, OSError) as err:  # OSError: the wheel's shared library failed to load
        raise ImportError(
            f"MeshSettings.mesher = 'gmsh' needs the optional gmsh package (GPL): {GMSH_INSTALL_HINT}"
        ) from err
    return gmsh


def gmsh_version() -> str:
    """The installed gmsh version (ImportError with the install hint if missing)."""
    return str(_import_gmsh().__version__)


# Signals whose actions gmsh's initialize sets to their defaults (measured with gmsh 4.15, even with
# interruptible=False): Python ignores SIGPIPE, so that a write to a closed pipe or socket is an error
# and not the end of the process (capture processes, stream servers), and faulthandler's handlers of the
# others report a crash. They are put back as they were.
_GMSH_RESETS = ("SIGPIPE", "SIGSEGV", "SIGFPE", "SIGBUS", "SIGILL")
_SIGACTION_BYTES = 512  # more than any platform's struct sigaction: kept and put back as opaque bytes


def _sigaction():
    """libc's ``sigaction`` (None where there is none, e.g. on Windows)."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).sigaction
    except (OSError, AttributeError, TypeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p]
    fn.restype = ctypes.c_int
    return fn


@contextmanager
def _signal_actions_kept() -> Iterator[None]:
    """The actions of :data:`_GMSH_RESETS` as they are now, restored whole (handler, mask, flags) on exit,
    from any thread (``sigaction`` is process-wide; Python's ``signal.signal`` works on the main thread only)."""
    sigaction = _sigaction()
    saved = []
    if sigaction is not None:
        for name in _GMSH_RESETS:
            num = getattr(signal, name, None)
            buf = ctypes.create_string_buffer(_SIGACTION_BYTES)
            if num is not None and sigaction(int(num), None, buf) == 0:
                saved.append((int(num), buf))
    try:
        yield
    finally:
        for num, buf in saved:
            sigaction(num, buf, None)


@contextmanager
def _session(gmsh, options: dict[str, float]) -> Iterator[None]:
    """A private gmsh model with ``options`` set; always cleaned up."""
    with _LOCK:
        owner = not gmsh.isInitialized()
        saved: dict[str, float] = {}
        if owner:
            # No signal handlers (they cannot be installed from a worker
            # thread) and no user configuration files (reproducible meshes).
            with _signal_actions_kept():
                gmsh.initialize(readConfigFiles=False, interruptible=False)
        try:
            for key, value in options.items():
                if not owner:
                    saved[key] = gmsh.option.getNumber(key)
                gmsh.option.setNumber(key, value)
            gmsh.model.add("twinsense-capacitive")
            yield
        finally:
            if owner:
                gmsh.finalize()
            else:
                gmsh.model.remove()
                for key, value in saved.items():
                    gmsh.option.setNumber(key, value)


def _cache_key(layout, settings, region, version: str) -> str:
    s = settings
    sizes = (s.h_min, s.h_max, s.growth, s.refine, s.h_refine)
    return f"gmsh-v1|gmsh {version}|{layout.digest_key()}|region {region!r}|sizes {sizes!r}"


def gmsh_layout_mesh(layout, settings, region: tuple) -> SimplexMesh:
    """Tetrahedral mesh of ``region`` with ``layout`` embedded (cached on disk).

    Parameters
    ----------
    layout : Layout
    settings : MeshSettings (h_min, h_max, growth, refine, h_refine, use_cache)
    region : (6,) float, the box (x_min, x_max, y_min, y_max, z_min, z_max) [m].

    Returns
    -------
    SimplexMesh, positively oriented tetrahedra [m].

    Raises
    ------
    ImportError
        gmsh is not installed (the message gives the install command).
    """
    gmsh = _import_gmsh()
    key = _cache_key(layout, settings, tuple(region), str(gmsh.__version__))
    return cached_mesh(key, lambda: _build(gmsh, layout, settings, region), use_cache=settings.use_cache)


def _build(gmsh, layout, s, region) -> SimplexMesh:
    x0, x1, y0, y1, z0, z1 = (float(v) for v in region)
    with _session(gmsh, {**_OPTIONS, "Mesh.MeshSizeMax": s.h_max}):
        occ = gmsh.model.occ
        tools = []
        sub = layout.substrate
        if sub is not None:
            ex = sub.extent if sub.extent is not None else (x0, x1, y0, y1)
            sx0, sx1 = max(ex[0], x0), min(ex[1], x1)
            sy0, sy1 = max(ex[2], y0), min(ex[3], y1)
            sz0, sz1 = max(-sub.thickness, z0), min(0.0, z1)
            if sx1 > sx0 and sy1 > sy0 and sz1 > sz0:
                tools.append((3, occ.addBox(sx0, sy0, sz0, sx1 - sx0, sy1 - sy0, sz1 - sz0)))
        electrode_surfaces = []
        solids = []
        for e in layout.electrodes:
            if isinstance(e, Electrode):
                for outer, holes in e.parts:
                    loops = [_curve_loop(occ, lp, e.z) for lp in (outer, *holes)]
                    electrode_surfaces.append((2, occ.addPlaneSurface(loops)))
            else:
                solids.append(e.bounds)
        box = occ.addBox(x0, y0, z0, x1 - x0, y1 - y0, z1 - z0)
        _, out_map = occ.fragment([(3, box)], tools + electrode_surfaces)
        occ.synchronize()
        # Fragments of the electrode surfaces (the last len(electrode_surfaces) inputs).
        pieces = [dt for m in out_map[1 + len(tools) :] for dt in m if dt[0] == 2]
        curves = sorted({abs(t) for _, t in gmsh.model.getBoundary(pieces, combined=False, oriented=False)})
        _size_fields(gmsh, s, curves, solids)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, tet_nodes = gmsh.model.mesh.getElementsByType(4)
    points = np.asarray(coords, float).reshape(-1, 3)
    tets = np.asarray(tet_nodes, np.int64).reshape(-1, 4)
    # gmsh tags are 1-based and may have gaps: renumber to the nodes the tets use.
    index = np.full(int(np.max(tags)) + 1, -1, np.int64)
    index[np.asarray(tags, np.int64)] = np.arange(len(tags))
    cells = index[tets]
    used = np.unique(cells)
    remap = np.full(len(points), -1, np.int64)
    remap[used] = np.arange(len(used))
    points = points[used]
    cells = remap[cells]
    return SimplexMesh(points, _oriented(points, cells))


def _curve_loop(occ, loop: np.ndarray, z: float) -> int:
    pts = [occ.addPoint(float(x), float(y), float(z)) for x, y in loop]
    lines = [occ.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
    return occ.addCurveLoop(lines)


def _size_fields(gmsh, s, curves: list[int], solids: list[np.ndarray]) -> None:
    """Background size: threshold on the distance to electrode outlines, refine and solid boxes."""
    field = gmsh.model.mesh.field
    occ = gmsh.model.occ
    ramp = 1.0 / (s.growth - 1.0)  # distance over which the size grows by one unit of length
    fields = []
    if curves:
        longest = max(occ.getMass(1, c) for c in curves)
        dist = field.add("Distance")
        field.setNumbers(dist, "CurvesList", curves)
        # The distance is taken to sample points along each curve: at most
        # h_min / 4 apart, so the size at the outline is h_min to 25 %.
        field.setNumber(dist, "Sampling", max(20, math.ceil(4.0 * longest / s.h_min)))
        thr = field.add("Threshold")
        field.setNumber(thr, "InField", dist)
        field.setNumber(thr, "SizeMin", s.h_min)
        field.setNumber(thr, "SizeMax", s.h_max)
        field.setNumber(thr, "DistMin", 0.0)
        field.setNumber(thr, "DistMax", (s.h_max - s.h_min) * ramp)
        fields.append(thr)
    boxes = [(b, min(h)) for b, h in s.refine_zones()]  # isotropic cells: the finest of a box's sizes
    boxes += [((b[0, 0], b[1, 0], b[0, 1], b[1, 1], b[0, 2], b[1, 2]), s.h_min) for b in solids]
    for b, h in boxes:
        f = field.add("Box")
        for name, value in zip(("XMin", "XMax", "YMin", "YMax", "ZMin", "ZMax"), b):
            field.setNumber(f, name, float(value))
        field.setNumber(f, "VIn", min(h, s.h_max))
        field.setNumber(f, "VOut", s.h_max)
        field.setNumber(f, "Thickness", max(s.h_max - h, 0.0) * ramp)
        fields.append(f)
    if not fields:
        return
    fmin = field.add("Min")
    field.setNumbers(fmin, "FieldsList", fields)
    field.setAsBackgroundMesh(fmin)
