"""A brute-force reference for the human-robot distance: points on a person's segments against a robot mesh.

Shared by the robot-cell tests that check SeparationMonitor's distance from outside.
"""

import math

import numpy as np

from twinsense.scene import Box, Sphere


def segment_samples(geometry, pose, h: float):
    """Points (n, 3) [m] of a body segment for a distance from below, its radius [m] and the sampling bound
    [m]: a box's six faces as grids of spacing <= h (a face point within h / sqrt(2) of one), a capsule's
    axis at spacing <= h (within h / 2; the radius is subtracted after)."""
    if isinstance(geometry, Box):
        size = np.asarray(geometry.size, dtype=float)
        faces = []
        for axis in range(3):
            for side in (-0.5, 0.5):
                grid = [np.linspace(-s / 2, s / 2, int(np.ceil(s / h)) + 1) for s in size]
                grid[axis] = np.array([side * size[axis]])
                faces.append(np.stack(np.meshgrid(*grid, indexing="ij"), -1).reshape(-1, 3))
        return pose.apply(np.concatenate(faces)), 0.0, h / math.sqrt(2.0)
    half = 0.0 if isinstance(geometry, Sphere) else 0.5 * geometry.height
    n = int(np.ceil(2 * half / h)) + 1
    return pose.apply(np.c_[np.zeros(n), np.zeros(n), np.linspace(-half, half, n)]), geometry.radius, h / 2


def person_to_mesh(person, t: float, robot, near, reach: float, h: float = 2e-3):
    """(distance [m], its sampling bound [m]) from ``person`` (an articulated body) at ``t`` to the trimesh
    ``robot``: trimesh's exact point-to-triangle distance from the segments' sample points, less the
    segment radius. Only points within ``reach`` [m] plus their radius of a point of the KD tree ``near``
    (points on the robot dense enough for that filter) are measured."""
    import trimesh

    body = person.state(t)
    ref, err = math.inf, 0.0
    for i, lk in enumerate(person.tree.links):
        if lk.geometry is None:
            continue
        pts, radius, e = segment_samples(lk.geometry, body.pose(i) @ lk.origin, h)
        keep = near.query(pts, distance_upper_bound=reach + radius)[0] < np.inf
        if keep.any():
            d = float(trimesh.proximity.closest_point(robot, pts[keep])[1].min()) - radius
            ref, err = (d, e) if d < ref else (ref, err)
    return ref, err
