"""Bind arbitrary points to a graph, so they follow its deformation.

Each point gets barycentric weights in one triangle of the graph: the triangle containing it,
or, for a point outside the shape (a Bezier handle, a stroke's edge), the nearest triangle,
whose affine map then carries it along. After a solve, all bound points are one sparse
matrix-vector product away. At rest the weights reproduce each point to rounding.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.spatial import cKDTree

__all__ = ["Binding", "bind"]

# Triangles looked at per point, nearest centroids first.
CANDIDATES = 12


class Binding:
    """Sparse weights taking graph positions to bound points.

    Parameters
    ----------
    weights : (p, n) scipy.sparse.csr_matrix
    """

    def __init__(self, weights):
        self.weights = csr_matrix(weights)

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
        return self.weights @ np.asarray(positions, dtype=np.float64)


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


def bind(graph, points):
    """Weights that carry ``points`` along with the graph.

    Parameters
    ----------
    graph : solver.Graph
    points : (p, 2) array_like
        Rest positions of the points to bind: inside, on, or outside the shape.

    Returns
    -------
    Binding

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
    triangles = graph.triangles
    if len(triangles) == 0:
        raise ValueError("the graph has no triangles to bind to")
    corners = graph.points[triangles]                     # (t, 3, 2)
    centroids = corners.mean(axis=1)
    k = min(CANDIDATES, len(triangles))
    _, nearest = cKDTree(centroids).query(points, k=k)
    nearest = nearest.reshape(len(points), k)
    a, b, c = (corners[nearest, j] for j in range(3))    # (p, k, 2)
    inside = points[:, None, :]
    bary = _barycentric(inside, a, b, c)                  # (p, k, 3)
    # Distance to each candidate triangle: zero inside, else to its nearest edge.
    outside = bary.min(axis=2) < -1e-12
    distance = np.minimum.reduce([_segment_distance(inside, a, b), _segment_distance(inside, b, c),
                                  _segment_distance(inside, c, a)])
    distance = np.where(outside, distance, 0.0)
    choice = np.argmin(distance, axis=1)                 # first containing triangle, else nearest
    rows = np.arange(len(points))
    chosen = nearest[rows, choice]
    weights = bary[rows, choice]
    matrix = csr_matrix((weights.ravel(), (np.repeat(rows, 3), triangles[chosen].ravel())),
                        shape=(len(points), graph.n))
    return Binding(matrix)
