"""Triangulations that respect a shape's boundary.

scipy's Delaunay (Qhull) knows nothing of the boundary, so a triangulation of boundary and
interior points can miss boundary segments where the shape is thin or sharply bent. We make
it conform the classic way: a boundary segment that is missing is split at its midpoint, and
interior points inside its diametral circle are dropped, until every segment is an edge.
Triangles outside the shape (in holes, notches and gaps) are then removed.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.spatial import Delaunay, QhullError, cKDTree

from .shapes import box_centre

__all__ = ["conforming_triangulation", "filtered_delaunay", "edges_of_triangles",
           "orient_counter_clockwise", "triangle_cross"]


def edges_of_triangles(triangles):
    """Unique undirected edges of a triangle list.

    Parameters
    ----------
    triangles : (t, 3) int ndarray

    Returns
    -------
    (k, 2) int64 ndarray
        Each edge once, smaller index first, sorted.
    """
    triangles = np.asarray(triangles, dtype=np.int64)
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    edges.sort(axis=1)
    return np.unique(edges, axis=0)


def triangle_cross(points, triangles):
    """Twice the signed area of each triangle: positive when counter-clockwise.

    Parameters
    ----------
    points : (n, 2) float ndarray
    triangles : (t, 3) int ndarray

    Returns
    -------
    (t,) float64 ndarray
    """
    a, b, c = (points[triangles[:, k]] for k in range(3))
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def orient_counter_clockwise(points, triangles):
    """Reorder triangle corners so every triangle is counter-clockwise."""
    triangles = np.array(triangles, dtype=np.int64)
    flip = triangle_cross(points, triangles) < 0
    triangles[flip] = triangles[flip][:, [0, 2, 1]]
    return triangles


def filtered_delaunay(points, geometry, min_area=0.0):
    """Delaunay triangles of ``points`` whose centroids lie inside ``geometry``.

    Parameters
    ----------
    points : (n, 2) float ndarray
    geometry : shapely geometry
        The shape; triangles in its holes and outside it are dropped.
    min_area : float
        Triangles with area at or below this are dropped (Qhull can return flat ones on
        collinear runs).

    Returns
    -------
    (t, 3) int64 ndarray
        Counter-clockwise triangles.

    Raises
    ------
    ValueError
        The points are too nearly on one line for Qhull.
    """
    # Qhull works in absolute coordinates: a shape far from the origin (a millionth of its
    # offset in size) loses the digits it needs and leaves boundary segments out, which the
    # conforming loop then splits round after round. Centred, it keeps them.
    try:
        simplices = Delaunay(points - box_centre(points)).simplices
    except QhullError:  # its points all but on one line, to the precision Qhull works at
        raise ValueError("the shape is too thin to triangulate: its points are on one line to "
                         "the precision Delaunay triangulation works at") from None
    centroid = points[simplices].mean(axis=1)
    cross = triangle_cross(points, simplices)
    inside = shapely.contains_xy(geometry, centroid[:, 0], centroid[:, 1])
    keep = inside & (0.5 * np.abs(cross) > min_area)
    return orient_counter_clockwise(points, simplices[keep])


def _segment_keys(first, second, n):
    lo, hi = np.minimum(first, second), np.maximum(first, second)
    return lo * n + hi


def conforming_triangulation(loops, interior, geometry, max_rounds=20):
    """Triangulate boundary loops and interior points so that every loop segment is an edge.

    Parameters
    ----------
    loops : list of (k_i, 2) float ndarray
        Boundary rings in order (their orientation is kept). Missing segments get their
        midpoints inserted, so the returned loops may be longer.
    interior : (q, 2) float ndarray
        Points strictly inside the shape. Points that block a boundary segment are dropped.
    geometry : shapely geometry
        The shape, for discarding triangles outside it.
    max_rounds : int
        Splitting rounds before giving up on the remaining segments (input with needle-sharp
        spikes); the triangulation is still valid, it just lacks those few segments.

    Returns
    -------
    points : (n, 2) float64 ndarray
        Loop points first, loop by loop, then the surviving interior points.
    loop_indices : list of (k_i', ) int64 ndarray
        Indices of each loop's points in ``points``, in order.
    triangles : (t, 3) int64 ndarray
        Counter-clockwise triangles.
    """
    loops = [np.asarray(loop, dtype=np.float64) for loop in loops]
    interior = np.asarray(interior, dtype=np.float64).reshape(-1, 2)
    scale = max(float(np.ptp(np.concatenate(loops), axis=0).max()), 1e-300)
    min_area = 1e-14 * scale * scale
    for _ in range(max_rounds):
        points = np.concatenate(loops + [interior])
        sizes = np.array([len(loop) for loop in loops])
        starts = np.concatenate([[0], np.cumsum(sizes)])
        triangles = filtered_delaunay(points, geometry, min_area)
        n = len(points)
        edge_keys = np.unique(_segment_keys(
            np.concatenate([triangles[:, 0], triangles[:, 1], triangles[:, 2]]),
            np.concatenate([triangles[:, 1], triangles[:, 2], triangles[:, 0]]), n))
        # Each loop's segments at once: a segment ends at the next point, the loop's first after
        # its last.
        following_index = np.arange(1, n + 1 - len(interior))
        following_index[starts[1:] - 1] = starts[:-1]
        boundary = points[:len(following_index)]
        keys = _segment_keys(np.arange(len(following_index)), following_index, n)
        found = np.minimum(np.searchsorted(edge_keys, keys), max(len(edge_keys) - 1, 0))
        # A segment shorter than this is not split: it cannot be recovered by splitting
        # (coincident points) and splitting it again would only multiply points.
        missing = ((edge_keys[found] != keys) if len(edge_keys) else np.ones(len(keys), bool)) & (
            np.linalg.norm(boundary[following_index] - boundary, axis=1) > 1e-7 * scale)
        missing_any = bool(missing.any())
        new_loops, blocked_centres, blocked_radii = [], [], []
        for loop, start in zip(loops, starts[:-1]):
            loop_missing = missing[start:start + len(loop)]
            if loop_missing.any():
                following = np.roll(loop, -1, axis=0)
                midpoints = 0.5 * (loop[loop_missing] + following[loop_missing])
                blocked_centres.append(midpoints)
                blocked_radii.append(0.5 * np.linalg.norm(following[loop_missing] - loop[loop_missing], axis=1))
                # Insert each midpoint right after the start of its segment.
                order = np.concatenate([np.arange(len(loop)), np.flatnonzero(loop_missing) + 0.5])
                loop = np.concatenate([loop, midpoints])[np.argsort(order, kind="stable")]
            new_loops.append(loop)
        if not missing_any:
            return points, [np.arange(s, e) for s, e in zip(starts[:-1], starts[1:])], triangles
        loops = new_loops
        if len(interior):
            centres = np.concatenate(blocked_centres)
            radii = np.concatenate(blocked_radii)
            near = cKDTree(interior).query_ball_point(centres, radii * (1.0 + 1e-9))
            drop = np.unique(np.concatenate([np.asarray(i, dtype=np.int64) for i in near] + [np.empty(0, np.int64)]))
            interior = np.delete(interior, drop, axis=0)
    points = np.concatenate(loops + [interior])
    sizes = np.array([len(loop) for loop in loops])
    starts = np.concatenate([[0], np.cumsum(sizes)])
    triangles = filtered_delaunay(points, geometry, min_area)
    return points, [np.arange(s, e) for s, e in zip(starts[:-1], starts[1:])], triangles
