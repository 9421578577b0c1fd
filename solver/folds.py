"""A penalty that keeps triangles from folding over: an addition to the paper's energy.

The paper's energy (equation 6) has minima with folded triangles in large bends, where a dragged
region meets the rest: nothing in it measures orientation. With ``Deformer(prevent_flips=True)``
each triangle of the graph whose signed area ``a`` falls below ``threshold`` times its rest
area ``a0`` adds ``weight * a0 * (threshold - a / a0)^2`` (``Options.fold_threshold`` and
``Options.fold_weight``, 0.1 and 100 by default). Above the threshold the term
is zero, so a pose that squeezes no triangle that far is a minimum of the paper's energy
unchanged; in big bends it holds the folds open at a small price in energy.

The weight per triangle scales with its area, as the paper's rows scale with their edges, so
the balance between the two does not depend on the graph's density. Its stiffness, though, goes
as ``1 / a0``: a near-degenerate triangle (two boundary points a hair apart, common where curve
segments meet) would be thousands of times stiffer than its neighbours, while its orientation
means nothing. Such slivers are weighted as if their area were ``Options.sliver_area`` times
their longest edge squared (0.05: a height under a tenth of the longest edge). On the benchmark character's standard drag (a boundary about six times
denser than its lattice), steps that barely moved the shape turned such triangles inside out
hundreds of times over, the line search halved up to 12 times per iteration, and the solve
stopped at its 30-iteration cap; with the bound (and :func:`solver.build_graph` merging ring
vertices a hair apart) it converges in 17 iterations with no folded triangle.

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
        Minus the penalty's scale where it is active: the Gauss-Newton part, ``s u u^T``,
        positive semi-definite.
    u : (t, 6) float ndarray
        The area's gradient on ``[x_a, x_b, x_c, y_a, y_b, y_c]``.
    bend : (t,) float ndarray
        ``s (floor - a)``: the weight of the area's own (indefinite) curvature, which the
        exact Hessian has and the Gauss-Newton part leaves out.
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
    """

    def __init__(self, graph, unknowns, threshold, weight, sliver_area):
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
        # weight * a0 * (threshold - a / a0)^2 = scale * (floor - a)^2, with a0 in the
        # scale bounded below for slivers.
        corners = graph.points[triangles]
        sides = corners - np.roll(corners, 1, axis=1)
        longest = np.einsum("tkc,tkc->tk", sides, sides).max(axis=1, initial=0.0)
        stiffness_area = np.maximum(rest_area, sliver_area * longest)
        self._scale = weight / np.where(rest_area > 0, stiffness_area, np.inf)
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
        slope = -self._scale[squeezed] * gap  # half of d energy / d area
        energy = -float(slope @ gap)
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
        coefficient = np.where(active, -self._scale, 0.0)
        bend = np.where(active, self._scale * (self._floor - area), 0.0)
        (x1, x2), (y1, y2) = edges
        u = np.empty((len(area), 6))
        u[:, 1], u[:, 4] = 0.5 * y2, -0.5 * x2      # d area / d b = d area / d e1
        u[:, 2], u[:, 5] = -0.5 * y1, 0.5 * x1      # d area / d c = d area / d e2
        u[:, 0] = -(u[:, 1] + u[:, 2])
        u[:, 3] = -(u[:, 4] + u[:, 5])
        return FoldTerms(coefficient, u, bend)
