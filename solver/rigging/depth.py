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
  sizes off its plane);
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

__all__ = ["HEIGHT_PER_SCORE", "MAX_SCORE", "AUTO_WEIGHT", "EDGE", "moved_score", "pin_weights", "heights", "stiffness",
           "reach_tints"]

HEIGHT_PER_SCORE = 0.02
# Pins' amounts add up without bound (an In Front typed as -1000 put the bar 20 of its sizes
# behind its plane): the order saturates at a lift of the shape's size, within which a drawing's
# stroke order still reads its layers (its rays start two sizes off the plane).
MAX_SCORE = 1.0 / HEIGHT_PER_SCORE
AUTO_WEIGHT = 0.5
EDGE = 0.3


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
    points = np.asarray(points, dtype=np.float64)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    pins = np.asarray(pins, dtype=np.int64).reshape(-1)
    extents = np.asarray(extents, dtype=np.float64).reshape(-1)
    if len(pins) == 0:
        return np.zeros((0, len(points)))
    lengths = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    n = len(points)
    graph = coo_matrix((lengths, (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    distance = dijkstra(graph, directed=False, indices=pins, limit=float(extents.max()))
    t = np.clip((1.0 - distance / np.maximum(extents[:, None], 1e-300)) / EDGE, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)  # smoothstep over the edge: no crease where it starts or ends


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
