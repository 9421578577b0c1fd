"""Depth where a posed shape overlaps itself: which layer is in front, as heights off the plane.

A pose can fold a flat shape over itself (an arm across the body). Both layers then lie in one
plane and renderers show a mosaic of the two. The rig lifts every graph point off the plane by
a small height, larger for what should be in front; the object's points get heights by the same
barycentric map as their positions, so renders, modifiers after the rig and exports all see it.

The order, per graph point, is a score:

- automatic: ``AUTO_WEIGHT`` times how far the point moved from its rest place, as a fraction
  of the shape's size (less the least any point moved), eased so that it stays below 1 (a
  hyperbolic tangent: within 8% of linear up to a drag of the shape's size). What was dragged
  across the shape (the arm) moved further than what it covers (the body), the score varies
  smoothly over the shape, a shape moved as a whole stays flat, and however far a handle goes
  the lift stays within a pin's (a handle keyed a million sizes away lifted the shape 10,000
  sizes off its plane). Only where the pose overlaps itself, and near there
  (:func:`automatic_reach`): elsewhere there is nothing to put in front, and a lift would push
  the shape through objects set just in front of it (QA: a body bent under a card 1 cm in
  front covered half of it);
- plus overlap pins: each adds its ``in_front`` amount (positive in front, negative behind)
  times its weight: 1 through the first ``1 - EDGE`` of its ``extent``, falling smoothly to 0 at
  the extent, measured through the rest shape along the graph's edges, so a pin on a hand does
  not reach the body across the gap between them. Where extents meet, the amounts add up. A
  pin's unit amount outweighs the automatic order of any drag.

Heights are ``HEIGHT_PER_SCORE`` of the size per unit of score: near rest (drags up to about the
shape's size, beyond which the easing shrinks it) a layer a tenth of the size further moved is
1e-3 of the size in front, what depth buffers need to separate the layers
cleanly (Cycles, EEVEE and Workbench, orthographic and perspective: the renders of
``tests/addon/test_overlap_depth.py``); a pin at 1
lifts its part 0.02 of the size, which a camera facing the plane does not see.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

__all__ = ["HEIGHT_PER_SCORE", "MAX_SCORE", "AUTO_WEIGHT", "EDGE", "OVERLAP_REACH", "moved_score", "automatic_reach",
           "edge_lengths", "pin_weights", "pin_reaches", "heights", "stiffness", "reach_tints"]

HEIGHT_PER_SCORE = 0.02
# Pins' amounts add up without bound (an In Front typed as -1000 put the bar 20 of its sizes
# behind its plane): the order saturates at a lift of the shape's size, within which a drawing's
# stroke order still reads its layers (its rays start two sizes off the plane).
MAX_SCORE = 1.0 / HEIGHT_PER_SCORE
AUTO_WEIGHT = 0.5
EDGE = 0.3
# How far from where the pose overlaps itself the automatic order fades out, along the rest
# graph's edges, as a fraction of the shape's size: far enough that the lift's slope stays
# small (2.6 degrees at the most the automatic order lifts), near enough to leave the rest of
# the shape in its plane.
OVERLAP_REACH = 0.2


def moved_score(rest, posed, size):
    """The automatic order: distance each point moved over the shape's size, less the least
    any point moved (a shape that only moved as a whole stays in its plane), eased below 1.

    Parameters
    ----------
    rest, posed : (n, 2) array_like
        Graph points at rest and posed.
    size : float
        The shape's size (its bounding box diagonal).

    Returns
    -------
    (n,) float64 ndarray
    """
    moved = np.linalg.norm(np.asarray(posed, dtype=np.float64) - np.asarray(rest, dtype=np.float64), axis=1)
    return np.tanh(AUTO_WEIGHT * (moved - moved.min()) / size) if len(moved) else moved


def automatic_reach(posed, triangles, lengths, size):
    """Where the automatic order applies: 1 where the posed shape overlaps itself (a point
    inside a posed triangle it is no corner of: a fold, or islands over one another), falling
    smoothly to 0 at ``OVERLAP_REACH`` of the size from there, along the rest graph's edges;
    0 everywhere when nothing overlaps.

    Parameters
    ----------
    posed : (n, 2) array_like
        Graph points posed.
    triangles : (t, 3) array_like of int
    lengths : (n, n) scipy.sparse matrix
        The rest graph's edge lengths (:func:`edge_lengths`; the same for every pose).
    size : float

    Returns
    -------
    (n,) float64 ndarray
    """
    inside = _covered(np.asarray(posed, dtype=np.float64), np.asarray(triangles, dtype=np.int64).reshape(-1, 3))
    if len(inside) == 0:
        return np.zeros(len(posed))
    extent = OVERLAP_REACH * size
    return _falloff(dijkstra(lengths, directed=False, indices=inside, min_only=True, limit=extent), extent)


def _covered(points, triangles):
    """The points (n, 2) strictly inside a triangle (t, 3) they are no corner of, (k,) sorted.

    Each point is tested against the triangles whose bounding boxes share its cell of a grid
    about a triangle's size (shapely's tree took 2.5 ms at 400 points and 30 ms at 4,000; this
    0.7 and 6)."""
    a, b, c = (points[triangles[:, i]] for i in range(3))
    low, high = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
    cell = max(float(np.sqrt(np.median((high[:, 0] - low[:, 0]) * (high[:, 1] - low[:, 1])))), 1e-300)
    origin = points.min(axis=0)
    first, last = ((np.floor((bound - origin) / cell)).astype(np.int64) for bound in (low, high))
    span = last - first + 1
    triangle = np.repeat(np.arange(len(triangles)), span[:, 0] * span[:, 1])
    k = _ranks(span[:, 0] * span[:, 1])
    columns = int(last[:, 0].max()) + 1
    keys = (first[triangle, 1] + k // span[triangle, 0]) * columns + first[triangle, 0] + k % span[triangle, 0]
    order = np.argsort(keys, kind="stable")
    keys, triangle = keys[order], triangle[order]
    cells = np.floor((points - origin) / cell).astype(np.int64)
    cells = np.minimum(cells[:, 1], int(last[:, 1].max())) * columns + np.minimum(cells[:, 0], columns - 1)
    start, stop = np.searchsorted(keys, cells, "left"), np.searchsorted(keys, cells, "right")
    point = np.repeat(np.arange(len(points)), stop - start)
    candidate = triangle[np.repeat(start, stop - start) + _ranks(stop - start)]
    not_corner = (triangles[candidate, 0] != point) & (triangles[candidate, 1] != point) & \
        (triangles[candidate, 2] != point)
    point, candidate = point[not_corner], candidate[not_corner]
    a, b, c, p = a[candidate], b[candidate], c[candidate], points[point]
    area = _cross(a, b, c)
    orientation, tolerance = np.sign(area), 1e-12 * np.abs(area)
    inside = (_cross(a, b, p) * orientation > tolerance) & (_cross(b, c, p) * orientation > tolerance) & \
        (_cross(c, a, p) * orientation > tolerance)
    return np.unique(point[inside])


def _ranks(counts):
    """0, 1, ..., counts[i] - 1 for each i in turn, (counts.sum(),)."""
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def _cross(u, v, w):
    """Twice the signed area of each triangle (u, v, w), (k, 2) each."""
    return (v[:, 0] - u[:, 0]) * (w[:, 1] - u[:, 1]) - (v[:, 1] - u[:, 1]) * (w[:, 0] - u[:, 0])


def pin_weights(points, edges, pins, extents):
    """Each pin's reach over the graph: 1 near the pin, falling smoothly to 0 at its extent.

    Distances are shortest paths along the graph's edges at rest, so a pin reaches only the
    part of the shape it is on, not a part across a gap.

    Parameters
    ----------
    points : (n, 2) array_like
        Rest graph points.
    edges : (e, 2) array_like of int
    pins : (k,) array_like of int
        The graph point each pin is bound to.
    extents : (k,) array_like of float
        How far each pin reaches, in the units of ``points``.

    Returns
    -------
    (k, n) float64 ndarray
    """
    pins = np.asarray(pins, dtype=np.int64).reshape(-1)
    extents = np.asarray(extents, dtype=np.float64).reshape(-1)
    if len(pins) == 0:
        return np.zeros((0, len(points)))
    distance = dijkstra(edge_lengths(points, edges), directed=False, indices=pins, limit=float(extents.max()))
    return _falloff(distance, extents[:, None])


def pin_reaches(points, edges, pin, extent, others, near):
    """Whether a pin at graph point ``pin`` reaching ``extent`` (:func:`pin_weights`) comes within
    ``near`` of any of ``others`` (m, 2): an object's own points, which are all that a lift moves
    (a low-poly mesh's quad corners may all lie beyond it)."""
    reached = np.asarray(points, dtype=np.float64)[pin_weights(points, edges, [pin], [extent])[0] > 0.0]
    others = np.asarray(others, dtype=np.float64).reshape(-1, 2)
    if not len(reached) or not len(others):
        return False
    distance, _ = cKDTree(reached).query(others, distance_upper_bound=near)
    return bool(np.isfinite(distance).any())


def edge_lengths(points, edges):
    """The graph's edges (e, 2) as a sparse (n, n) matrix of their lengths at ``points`` (n, 2)."""
    points = np.asarray(points, dtype=np.float64)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    lengths = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    return coo_matrix((lengths, (edges[:, 0], edges[:, 1])), shape=(len(points), len(points))).tocsr()


def _falloff(distance, extent):
    """1 up to ``1 - EDGE`` of ``extent``, falling to 0 at it, a smoothstep over the edge so that
    there is no crease where it starts or ends."""
    t = np.clip((1.0 - distance / np.maximum(extent, 1e-300)) / EDGE, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def heights(score, size, pin_amounts=None, weights=None):
    """Heights off the plane (n,) for the automatic ``score`` and overlap pins.

    Parameters
    ----------
    score : (n,) array_like
        From :func:`moved_score`.
    size : float
    pin_amounts : (k,) array_like, optional
        Each overlap pin's ``in_front``.
    weights : (k, n) array_like, optional
        From :func:`pin_weights`.

    Returns
    -------
    (n,) float64 ndarray
    """
    total = np.asarray(score, dtype=np.float64).copy()
    if pin_amounts is not None and len(pin_amounts):
        total += np.asarray(pin_amounts, dtype=np.float64) @ np.asarray(weights, dtype=np.float64)
    return HEIGHT_PER_SCORE * size * np.clip(total, -MAX_SCORE, MAX_SCORE)


def stiffness(amounts, weights):
    """Per point, 1 plus each starch pin's stiffness times its weight there: the factor the
    deformer weighs each point's energy terms by.

    Parameters
    ----------
    amounts : (k,) array_like
        Each starch pin's ``stiffness``.
    weights : (k, n) array_like
        From :func:`pin_weights`.

    Returns
    -------
    (n,) float64 ndarray, or None without pins
    """
    if not len(amounts):
        return None
    return 1.0 + np.asarray(amounts, dtype=np.float64) @ np.asarray(weights, dtype=np.float64)


def reach_tints(in_front, overlap_weights, stiffnesses, starch_weights, opacity, starch_color, full_stiffness=10.0):
    """The points pins reach and how an overlay tints them: overlap pins white where their summed
    amount brings the shape in front, black where it sends it behind, as opaque as that amount
    (``opacity`` at 1 or more); then starch pins in ``starch_color``, as opaque as their summed
    stiffness over ``full_stiffness``.

    Parameters
    ----------
    in_front : (k,) array_like
    overlap_weights : (k, n) array_like
        From :func:`pin_weights`, for the overlap pins.
    stiffnesses : (s,) array_like
    starch_weights : (s, n) array_like
        From :func:`pin_weights`, for the starch pins.
    opacity : float
    starch_color : (4,) array_like
        RGBA; its alpha is the most a starched point gets.
    full_stiffness : float

    Returns
    -------
    points : (m,) int64 ndarray
        Graph points, overlap-reached first (a point reached by both kinds appears twice).
    colors : (m, 4) float32 ndarray
    """
    strength = np.asarray(in_front, dtype=np.float64)[:, None] * np.asarray(overlap_weights, dtype=np.float64)
    reached = np.flatnonzero(np.abs(strength).sum(axis=0) > 0)
    total = strength[:, reached].sum(axis=0)
    colors = np.zeros((len(reached), 4), np.float32)
    colors[:, :3] = (total > 0)[:, None]
    colors[:, 3] = np.minimum(np.abs(total), 1.0) * opacity
    stiff = stiffness(stiffnesses, starch_weights)
    starched = np.flatnonzero(stiff > 1.0) if stiff is not None else np.empty(0, np.int64)
    starch_colors = np.tile(np.asarray(starch_color, np.float32), (len(starched), 1))
    starch_colors[:, 3] *= np.minimum((stiff[starched] - 1.0) / full_stiffness, 1.0) if len(starched) else 1.0
    return np.concatenate([reached, starched]), np.concatenate([colors, starch_colors])
