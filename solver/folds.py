"""A penalty that keeps triangles from folding over: an addition to the paper's energy.

The paper's energy (equation 6) has minima with folded triangles in large bends, where a dragged
region meets the rest: nothing in it measures orientation. With ``Deformer(prevent_flips=True)``
each triangle of the graph whose area ratio ``r = a / a0`` (signed area over rest area) falls
below ``t`` adds ``w * a0 * (t - r)^3 / (3 t^2)`` (``t = Options.fold_threshold``,
``w = Options.fold_weight``, 0.4 and 20 by default). Above the threshold the term is zero, so
a pose that squeezes no triangle that far is a minimum of the paper's energy unchanged; in big
bends it holds the folds open at a small price in energy.

``w`` is the push at zero area: a triangle's term falls by ``w a0`` per unit of ``r`` as it
reopens from ``r = 0``, and more steeply as it turns further inside out. Triangles with a corner
held by a handle get ``Options.fold_weight_at_handles`` times ``w`` (3): a handle region moves
rigidly, and the free points beside it take the squeeze its turn concentrates there (the folds
the penalty left at the paper's size were all of such triangles). The cube makes the
penalty's curvature grow from zero at the threshold, so the Newton model has no jump there: a
quadratic penalty (``t = 0.1``, with ``w`` giving the same push) put a stiff wall at its
threshold, and solves that pressed on it crawled along it for tens of iterations. The
measurements behind both constants are in ``docs/solver_options.md``.

The weight per triangle scales with its area, as the paper's rows scale with their edges. A
fold is a local event, though: on a dense graph the energy's minima fold a few small triangles
where a coarse one holds, so with the density normalisation the deformer multiplies ``w`` by
the square of the reference spacing over the graph's, and every triangle is held open as firmly
as one at the reference spacing (measured in ``docs/solver_options.md``). The stiffness goes
as ``1 / a0``: a near-degenerate triangle (two boundary points a hair apart, common where curve
segments meet) would be thousands of times stiffer than its neighbours, while its orientation
means nothing, and steps that barely move the shape turn it inside out again and again. Such
slivers are weighted as if their area were ``Options.sliver_area`` times their longest edge
squared (0.05: a height under a tenth of the longest edge); :func:`solver.build_graph` also
merges ring vertices a hair apart.

Areas are quadratic in the positions: with a triangle's edge vectors ``e1 = b - a`` and
``e2 = c - a`` (rows of a constant matrix, like ``A``'s), ``area = (e1 x e2) / 2``, so values and
gradients are sparse mat-vecs.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.sparse import coo_matrix

from .triangulate import triangle_cross

__all__ = ["FoldPenalty", "FoldTerms"]

# The Hessian of a triangle's signed area on [x_a, x_b, x_c, y_a, y_b, y_c]: the area is
# (x^T S y) / 2 with S the skew-symmetric cyclic matrix below, so the Hessian is constant.
_CYCLIC = np.array([[0.0, 1.0, -1.0], [-1.0, 0.0, 1.0], [1.0, -1.0, 0.0]])
AREA_HESSIAN = 0.5 * np.block([[np.zeros((3, 3)), _CYCLIC], [_CYCLIC.T, np.zeros((3, 3))]])


class FoldTerms(NamedTuple):
    """The penalty's half Hessian at a pose, per triangle:
    ``-coefficient u u^T - bend * AREA_HESSIAN`` (both zero where a triangle is not squeezed).

    Attributes
    ----------
    coefficient : (t,) float ndarray
        Minus half the term's second derivative by the area: the Gauss-Newton part,
        ``-coefficient u u^T``, positive semi-definite.
    u : (t, 6) float ndarray
        The area's gradient on ``[x_a, x_b, x_c, y_a, y_b, y_c]``.
    bend : (t,) float ndarray
        Minus half the term's derivative by the area: the weight of the area's own
        (indefinite) curvature, which the exact Hessian has and the Gauss-Newton part leaves out.
    """

    coefficient: np.ndarray
    u: np.ndarray
    bend: np.ndarray


class FoldPenalty:
    """The fold penalty on the stacked free coordinates ``v = [x; y]`` of a deformer.

    Parameters
    ----------
    graph : solver.Graph
    unknowns : solver.unknowns.Unknowns
        The deformer's split into free and fixed points.
    threshold, weight, sliver_area : float
        ``Options.fold_threshold``, ``Options.fold_weight`` and ``Options.sliver_area``.
    at_handles : float
        ``Options.fold_weight_at_handles``: the factor on ``weight`` for triangles with a corner
        held by a handle.
    stiffness : (n,) array_like, optional
        The energy's factor per point (:class:`solver.energy.Energy`): each triangle's term is
        weighed by its corners' mean, as the energy's rows are, so a starched region is held
        open as firmly, relative to its stiffer energy, as the rest (unscaled, the stiffer
        energy overpowered the penalty there and folded triangles no pose without it folded;
        a stiffness the same everywhere scales the whole energy and changes no pose).
    """

    def __init__(self, graph, unknowns, threshold, weight, sliver_area, at_handles=1.0, stiffness=None):
        triangles = graph.triangles
        count = len(triangles)
        ones = np.ones(count)
        first, second = np.arange(count), count + np.arange(count)
        # Rows 0..t-1: e1 = b - a; rows t..2t-1: e2 = c - a.
        edges = coo_matrix((np.concatenate([ones, -ones, ones, -ones]),
                            (np.concatenate([first, first, second, second]),
                             np.concatenate([triangles[:, 1], triangles[:, 0], triangles[:, 2], triangles[:, 0]]))),
                           shape=(2 * count, graph.n))
        self._free_block, self._free_block_transpose, self._fixed_columns = unknowns.split(edges)
        self._fixed_edges = np.zeros(4 * count)
        rest_area = 0.5 * triangle_cross(graph.points, triangles)
        # w a0 (t - a / a0)^3 / (3 t^2) = scale (floor - a)^3 with floor = t a0 and
        # scale = w / (3 t^2 a0^2), a0 in the scale bounded below for slivers.
        corners = graph.points[triangles]
        sides = corners - np.roll(corners, 1, axis=1)
        longest = np.einsum("tkc,tkc->tk", sides, sides).max(axis=1, initial=0.0)
        stiffness_area = np.maximum(rest_area, sliver_area * longest)
        self._scale = weight / (3.0 * threshold ** 2 * np.where(rest_area > 0, stiffness_area, np.inf) ** 2)
        held = np.zeros(graph.n, dtype=bool)
        held[unknowns.fixed] = True
        self._scale[held[triangles].any(axis=1)] *= at_handles
        if stiffness is not None:
            self._scale *= np.asarray(stiffness, dtype=np.float64).reshape(-1)[triangles].mean(axis=1)
        self._floor = threshold * rest_area
        self.triangles = triangles

    def hold(self, fixed_positions):
        """Take the fixed points' positions ``(c, 2)`` for the solve that follows."""
        self._fixed_edges = (self._fixed_columns @ fixed_positions).T.ravel()

    def _areas(self, v):
        """Edge vectors ``(2, 2, t)`` (coordinate, edge, triangle) and signed areas ``(t,)``."""
        edges = (self._fixed_edges + self._free_block @ v).reshape(2, 2, -1)
        (x1, x2), (y1, y2) = edges
        return edges, 0.5 * (x1 * y2 - y1 * x2)

    def evaluate(self, v):
        """The penalty and half its gradient.

        Parameters
        ----------
        v : (2 f,) float ndarray

        Returns
        -------
        energy : float
        half_gradient : (2 f,) float64 ndarray, or None
            None when no triangle is squeezed (energy and gradient are zero).
        """
        edges, area = self._areas(v)
        gap = self._floor - area
        squeezed = np.flatnonzero(gap > 0.0)
        if len(squeezed) == 0:
            return 0.0, None
        # Only the few squeezed triangles have a term: work on those, scatter into the edges.
        gap = gap[squeezed]
        slope = -1.5 * self._scale[squeezed] * gap * gap  # half of d energy / d area
        energy = -float(slope @ gap) / 1.5
        half = 0.5 * slope
        (x1, x2), (y1, y2) = edges[..., squeezed]
        # The area's derivatives by the two edges, coordinate-major as the edges are.
        by_edge = np.zeros_like(edges)
        by_edge[0, 0, squeezed] = half * y2
        by_edge[0, 1, squeezed] = -half * y1
        by_edge[1, 0, squeezed] = -half * x2
        by_edge[1, 1, squeezed] = half * x1
        return energy, self._free_block_transpose @ by_edge.ravel()

    def terms(self, v):
        """The penalty's Hessian terms for :class:`~solver.hessian.Hessian`.

        Returns
        -------
        FoldTerms or None
            None where no triangle is squeezed (the penalty has no curvature there).
        """
        edges, area = self._areas(v)
        active = area < self._floor
        if not active.any():
            return None
        gap = np.where(active, self._floor - area, 0.0)
        coefficient = -3.0 * self._scale * gap
        bend = 1.5 * self._scale * gap * gap
        (x1, x2), (y1, y2) = edges
        u = np.empty((len(area), 6))
        u[:, 1], u[:, 4] = 0.5 * y2, -0.5 * x2      # d area / d b = d area / d e1
        u[:, 2], u[:, 5] = -0.5 * y1, 0.5 * x1      # d area / d c = d area / d e2
        u[:, 0] = -(u[:, 1] + u[:, 2])
        u[:, 3] = -(u[:, 4] + u[:, 5])
        return FoldTerms(coefficient, u, bend)
