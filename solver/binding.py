"""Bind arbitrary points to a graph, so they follow its deformation.

A point inside the shape gets the barycentric weights of the triangle containing it. A point
outside the shape gets a blend of the affine maps of the triangles
along the nearest stretch of boundary: each boundary edge within a window of the nearest one
weighs in, fading to zero at the window's edge. The window is half the point's distance to the
shape (at most ``BLEND_WINDOW`` of its size), so the weights change continuously as a point
moves, also where the nearest boundary jumps from one side of a notch to the other (between a
horse's legs, a point following only its nearest triangle jumped by up to 15% of the size), and
they shrink to the containing triangle's as the point reaches the boundary. Every triangle's
affine map reproduces the point at rest, so any blend of them does: at rest the weights
reproduce each point to rounding, and a rigid motion of the graph moves every bound point
rigidly. After a solve, all bound points are one sparse matrix-vector product away.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.spatial import cKDTree

from .shapes import box_centre

__all__ = ["Binding", "bind"]

# Triangles (by nearest centroid) or boundary edges (by nearest midpoint) looked at first per
# point; more are looked at for points where these might miss one that matters.
CANDIDATES = 12
# Positions whose centre lies more than FAR times their extent from the origin are applied
# about their centre.
FAR = 1000.0
# Barycentric coordinates above -INSIDE count as inside a triangle.
INSIDE = 1e-12
# Triangles whose doubled area is below FLAT times their longest side squared are not bound to.
FLAT = 1e-9
# Outside the shape, boundary edges up to this fraction of the point's distance farther than
# the nearest one blend in...
BLEND_RELATIVE = 0.5
# ...and never more than this fraction of the graph's size farther.
BLEND_WINDOW = 0.05


class Binding:
    """Sparse weights taking graph positions to bound points.

    Parameters
    ----------
    weights : (p, n) scipy.sparse.csr_matrix
    """

    def __init__(self, weights):
        self.weights = csr_matrix(weights)
        self._row_sums = np.asarray(self.weights.sum(axis=1)).ravel()

    def __len__(self):
        return self.weights.shape[0]

    def apply(self, positions):
        """Bound points for graph ``positions``.

        Parameters
        ----------
        positions : (n, 2) array_like

        Returns
        -------
        (p, 2) float64 ndarray
        """
        positions = np.asarray(positions, dtype=np.float64)
        if len(positions) == 0:
            return self.weights @ positions
        low, high = positions.min(axis=0), positions.max(axis=0)
        centre = 0.5 * (low + high)
        if np.abs(centre).max() <= FAR * np.abs(high - low).max():
            return self.weights @ positions
        # Far from the origin, applied about the positions' centre (added back weighted by each
        # row's sum), so the digits that extrapolated weights outside the shape would multiply
        # away are kept.
        result = self.weights @ (positions - centre)
        result += self._row_sums[:, None] * centre
        return result


def _barycentric(points, a, b, c):
    """Barycentric coordinates of points (..., 2) in triangles a, b, c (..., 2)."""
    v0, v1, v2 = b - a, c - a, points - a
    d00 = np.einsum("...i,...i", v0, v0)
    d01 = np.einsum("...i,...i", v0, v1)
    d11 = np.einsum("...i,...i", v1, v1)
    d20 = np.einsum("...i,...i", v2, v0)
    d21 = np.einsum("...i,...i", v2, v1)
    denominator = d00 * d11 - d01 * d01
    denominator = np.where(denominator == 0, 1e-300, denominator)
    v = (d11 * d20 - d01 * d21) / denominator
    w = (d00 * d21 - d01 * d20) / denominator
    return np.stack([1.0 - v - w, v, w], axis=-1)


def _segment_distance(points, a, b):
    ab = b - a
    t = np.einsum("...i,...i", points - a, ab) / np.maximum(np.einsum("...i,...i", ab, ab), 1e-300)
    closest = a + np.clip(t, 0.0, 1.0)[..., None] * ab
    return np.linalg.norm(points - closest, axis=-1)


def _search(tree, points, settle, most=None):
    """Hand each point's nearest tree items to ``settle`` until it settles the point.

    ``settle(rows, distances, nearest, last)`` gets point row numbers ``(q,)`` with the
    distances ``(q, k)`` (sorted) and indices ``(q, k)`` of their ``k`` nearest items, records
    what it can decide and returns a ``(q,)`` mask of the rows it settled. ``k`` starts at
    ``CANDIDATES`` and grows fourfold for the rest, up to ``most`` (default: every item); in
    that round ``last`` is True and every row must be settled.
    """
    most = tree.n if most is None else min(most, tree.n)
    rows = np.arange(len(points))
    k = min(CANDIDATES, most)
    while len(rows):
        last = k == most
        kept = []
        for chunk in np.array_split(rows, max(1, len(rows) * k // 2_000_000)):  # bound the memory
            distances, nearest = tree.query(points[chunk], k=k)
            settled = settle(chunk, distances.reshape(len(chunk), k), nearest.reshape(len(chunk), k), last)
            kept.append(chunk[~settled])
        rows = np.concatenate(kept)
        k = min(4 * k, most)


def _containing(points, corners):
    """The triangle containing each point, or -1, and the point's barycentric coordinates in it.

    Parameters
    ----------
    points : (p, 2) float ndarray
    corners : (t, 3, 2) float ndarray

    Returns
    -------
    chosen : (p,) int64 ndarray
        Index of the containing triangle; -1 for points in none.
    weights : (p, 3) float64 ndarray
    """
    centroids = corners.mean(axis=1)
    # No triangle contains a point farther from its centroid than its farthest corner: once the
    # k-th nearest centroid is farther than the largest such reach, none was missed. (A mesh
    # with a few huge triangles would make that a search through all of them; a few hundred
    # candidates are enough for any fair triangulation.)
    reach = np.sqrt(((corners - centroids[:, None]) ** 2).sum(axis=2).max(initial=0.0))
    chosen = np.full(len(points), -1, dtype=np.int64)
    weights = np.zeros((len(points), 3))

    def settle(rows, distances, nearest, last):
        bary = _barycentric(points[rows, None], *(corners[nearest, j] for j in range(3)))
        inside = bary.min(axis=2) >= -INSIDE
        hit = inside.any(axis=1)
        first = np.argmax(inside, axis=1)[hit]
        chosen[rows[hit]] = nearest[hit, first]
        weights[rows[hit]] = bary[hit, first]
        return hit | (distances[:, -1] > reach) | last

    _search(cKDTree(centroids), points, settle, most=16 * 16 * CANDIDATES)
    return chosen, weights


def _boundary_edges(triangles, n):
    """Edges of exactly one triangle: ``(m, 2)`` point indices and ``(m,)`` owning triangles."""
    directed = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    owner = np.tile(np.arange(len(triangles)), 3)
    keys = np.minimum(directed[:, 0], directed[:, 1]) * n + np.maximum(directed[:, 0], directed[:, 1])
    _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    lone = counts[inverse] == 1
    return directed[lone], owner[lone]


def _exterior_weights(points, graph_points, triangles, size):
    """Blended weights of points outside the triangulation (see the module docstring).

    Returns
    -------
    rows, columns, values : (e,) ndarrays
        Entries of the weight matrix, rows numbered as ``points``; duplicates are to be summed.
    """
    edges, owner = _boundary_edges(triangles, len(graph_points))
    if len(edges) == 0:  # a closed triangulation has no outside; keep its own points still
        edges, owner = np.stack([triangles[:, 0], triangles[:, 1]], axis=1), np.arange(len(triangles))
    start, end = graph_points[edges[:, 0]], graph_points[edges[:, 1]]
    half = 0.5 * float(np.linalg.norm(end - start, axis=1).max())
    entries = []

    def settle(rows, distances, nearest, last):
        distance = _segment_distance(points[rows, None], start[nearest], end[nearest])  # (q, k)
        closest = distance.min(axis=1)
        window = np.minimum(BLEND_RELATIVE * closest, BLEND_WINDOW * size)
        # Every edge within the window has its midpoint within this radius.
        done = (distances[:, -1] > closest + window + half) | last
        distance, closest, window = distance[done], closest[done, None], window[done, None]
        fade = np.square(np.clip(1.0 - (distance - closest) / np.where(window > 0, window, 1.0), 0.0, 1.0))
        fade = np.where(window > 0, fade, distance == closest)  # on the boundary: the nearest edge
        fade /= fade.sum(axis=1, keepdims=True)
        rows, triangle = rows[done], owner[nearest[done]]                     # (q,), (q, k)
        corners = triangles[triangle]                                         # (q, k, 3)
        bary = _barycentric(points[rows, None], *(graph_points[corners[..., j]] for j in range(3)))
        used = fade > 0
        entries.append((np.broadcast_to(rows[:, None, None], corners.shape)[used].ravel(),
                        corners[used].ravel(), (fade[..., None] * bary)[used].ravel()))
        return done

    _search(cKDTree(0.5 * (start + end)), points, settle)
    if not entries:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    return tuple(np.concatenate(part) for part in zip(*entries))


def bind(graph, points):
    """Weights that carry ``points`` along with the graph.

    Parameters
    ----------
    graph : solver.Graph
        Or anything with ``points`` (n, 2) and ``triangles`` (t, 3).
    points : (p, 2) array_like
        Rest positions of the points to bind: inside, on, or outside the shape.

    Returns
    -------
    Binding
        Barycentric weights of the containing triangle for points inside; for points outside,
        a blend over the nearest stretch of boundary that varies continuously with the point.

    Raises
    ------
    ValueError
        Points of the wrong shape or not finite, or a graph without triangles.
    """
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"points must be a (p, 2) array, got shape {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError("points have non-finite coordinates (NaN or inf)")
    triangles = np.asarray(graph.triangles, dtype=np.int64)
    if len(triangles) == 0:
        raise ValueError("the graph has no triangles to bind to")
    # Barycentric coordinates from coordinates centred on the graph keep their digits when the
    # shape lies far from the origin.
    graph_points = np.asarray(graph.points, dtype=np.float64)
    centre = box_centre(graph_points)
    graph_points, points = graph_points - centre, points - centre
    # Flat triangles carry no affine map worth following (their barycentric coordinates blow
    # up); their neighbours cover the same ground.
    corners = graph_points[triangles]
    sides = corners - np.roll(corners, 1, axis=1)
    cross = np.abs(sides[:, 0, 0] * sides[:, 1, 1] - sides[:, 0, 1] * sides[:, 1, 0])
    fair = cross > FLAT * np.einsum("tkc,tkc->tk", sides, sides).max(axis=1)
    if fair.any():
        triangles = triangles[fair]
    chosen, weights = _containing(points, graph_points[triangles])
    inside = np.flatnonzero(chosen >= 0)
    rows = [np.repeat(inside, 3)]
    columns = [triangles[chosen[inside]].ravel()]
    values = [weights[inside].ravel()]
    outside = np.flatnonzero(chosen < 0)
    if len(outside):
        size = float(np.linalg.norm(np.ptp(graph_points, axis=0)))
        local, column, value = _exterior_weights(points[outside], graph_points, triangles, size)
        rows.append(outside[local])
        columns.append(column)
        values.append(value)
    matrix = csr_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(columns))),
                        shape=(len(points), len(graph_points)))
    matrix.sum_duplicates()
    return Binding(matrix)
