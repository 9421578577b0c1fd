"""The global area constraint of the paper's section 5 (problem (10)), met exactly at every iterate.

The signed area of all boundary loops (islands minus holes) is quadratic in the positions, so
along any direction the correction that restores it is a root of a quadratic
(:meth:`AreaConstraint.restore`), and a start far from the rest area (after an extreme drag) is
first projected onto it (:meth:`AreaConstraint.project`). The optimiser projects each step onto
the constraint's tangent in the metric of its preconditioner (:func:`tangent`) and measures
curvature with the Lagrangian's gradient (:func:`multiplier`): the paper's Lagrange step after
(13), ``h = -H^-1 (A^T S + J^T lambda)``, with ``H`` whatever matrix the optimiser steps with in
place of its ``A^T A``, and the constraint's residual ``t`` zero because every iterate is on it.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix

from .shapes import box_centre

__all__ = ["AreaConstraint", "multiplier", "tangent"]

# The constraint is met to this fraction of the rest area (rounding in the shoelace sum of a
# 12,000-point boundary alone is 1e-12); a pose so large that its own sum rounds worse is held
# to that rounding, ROUNDING times the sum of the magnitudes of its terms.
AREA_TOLERANCE = 1e-10
ROUNDING = 1e-13
# Steps the projection of a start onto the constraint takes at most (one, unless the start is
# far from the rest area).
PROJECTION_STEPS = 50


class AreaConstraint:
    """Signed area of all boundary loops, a quadratic form in the stacked free coordinates.

    With all coordinates stacked ``p = [x; y]`` the shoelace sum is ``area = p^T Q p / 2`` for a
    constant sparse ``Q``. Splitting ``p`` into free (``v``) and fixed (``c``) parts gives
    ``area(v) = v^T Q_ff v / 2 + v . (Q_fc c) + c^T Q_cc c / 2`` and ``d area / dv = Q_ff v + Q_fc c``.
    """

    def __init__(self, graph, free, fixed):
        n = graph.n
        here = graph.boundary
        after = np.concatenate([np.roll(loop, -1) for loop in graph.boundary_loops])
        half = np.full(len(here), 0.5)
        # x_here * y_after / 2 - x_after * y_here / 2, symmetrised.
        shoelace = coo_matrix((np.concatenate([half, -half]),
                               (np.concatenate([here, after]), np.concatenate([n + after, n + here]))),
                              shape=(2 * n, 2 * n)).tocsr()
        shoelace = (shoelace + shoelace.T).tocsr()
        stacked_free = np.concatenate([free, n + free])
        stacked_fixed = np.concatenate([fixed, n + fixed])
        rows_free = shoelace[stacked_free]
        self._free_free = rows_free[:, stacked_free].tocsr()
        self._free_fixed = rows_free[:, stacked_fixed].tocsr()
        self._fixed_fixed = shoelace[stacked_fixed][:, stacked_fixed].tocsr()
        self._free_free_magnitude = abs(self._free_free)
        self._fixed_magnitude = (np.zeros(len(stacked_free)), 0.0)
        centred = graph.points - box_centre(graph.points)
        rest = np.concatenate([centred[:, 0], centred[:, 1]])
        self.rest = 0.5 * float(rest @ (shoelace @ rest))
        self._linear = np.zeros(len(stacked_free))
        self._constant = 0.0

    def hold(self, fixed_coordinates):
        """Take the fixed points' stacked coordinates ``(2 c,)`` for the solve that follows."""
        self._linear = self._free_fixed @ fixed_coordinates
        self._constant = 0.5 * float(fixed_coordinates @ (self._fixed_fixed @ fixed_coordinates))
        magnitude = np.abs(fixed_coordinates)
        self._fixed_magnitude = (abs(self._free_fixed) @ magnitude,
                                 0.5 * float(magnitude @ (abs(self._fixed_fixed) @ magnitude)))

    def met(self, v, rounding=False):
        """Whether the area at ``v`` is the rest area to ``AREA_TOLERANCE``; with ``rounding``,
        or to the rounding of its own sum, when that is larger (at a pose so large that this is
        all float64 can tell: a start after an extreme drag of a needle-spiked shape reached
        5,000 times the shape's size)."""
        bound = AREA_TOLERANCE * abs(self.rest)
        if rounding:
            linear, constant = self._fixed_magnitude
            magnitude = np.abs(v)
            terms = 0.5 * float(magnitude @ (self._free_free_magnitude @ magnitude))
            terms += float(linear @ magnitude) + constant
            bound = max(bound, ROUNDING * terms)
        return abs(self.area(v) - self.rest) <= bound

    def area(self, v):
        """The shape's signed area at free coordinates ``v`` (2 f,), the fixed points held."""
        return 0.5 * float(v @ (self._free_free @ v)) + float(self._linear @ v) + self._constant

    def jacobian(self, v):
        """d area / d v, stacked ``(2 f,)``."""
        return self._free_free @ v + self._linear

    def restore(self, v, direction):
        """Move ``v`` along ``direction`` so its area is the rest area; False if it cannot."""
        a = 0.5 * float(direction @ (self._free_free @ direction))
        b = float(self.jacobian(v) @ direction)
        c = self.area(v) - self.rest
        if abs(a) <= 1e-14 * abs(b):
            if b == 0.0:
                return c == 0.0
            mu = -c / b
        else:
            discriminant = b * b - 4.0 * a * c
            if discriminant < 0.0:
                return False
            root = np.sqrt(discriminant)
            # The smaller correction; written to avoid cancellation.
            q = -0.5 * (b + np.copysign(root, b))
            candidates = [q / a, c / q] if q != 0.0 else [0.0]
            mu = min(candidates, key=abs)
        v += mu * direction
        return True

    def project(self, v, directions):
        """Move ``v`` (in place) to the rest area; False if ``PROJECTION_STEPS`` do not get there
        (or to the rounding of the area's sum, see :meth:`met`).

        ``directions(jacobian)`` gives the direction to move along (the solver's ``H^-1 J``). When
        the area cannot reach the rest area along it (a start far from it, after an extreme
        drag: the area's curvature along the line turns it back first), the area's own gradient
        is tried, and failing that the step goes along the gradient to where the area is nearest
        the rest area, and a new direction is taken from there.
        """
        for _ in range(PROJECTION_STEPS):
            if self.met(v):
                return True
            jacobian = self.jacobian(v)
            if self.restore(v, directions(jacobian)) or self.restore(v, jacobian):
                continue
            # Along the area's own gradient, go to where the area is nearest the rest area.
            curvature = float(jacobian @ (self._free_free @ jacobian))
            slope = float(jacobian @ jacobian)
            if curvature == 0.0 or slope == 0.0:
                return False
            v -= (slope / curvature) * jacobian
        return self.met(v, rounding=True)


def multiplier(gradient, jacobian, direction):
    """Least-squares Lagrange multiplier of the area constraint in the metric of H: the paper's
    ``lambda`` after (13) with ``t = 0``, ``gradient @ H^-1 J / (J @ H^-1 J)``.

    Parameters
    ----------
    gradient, jacobian, direction : (2 f,) float ndarray
        The energy's gradient, the area's (``J``), and ``H^-1 J``.

    Returns
    -------
    float
    """
    along = float(jacobian @ direction)
    if along <= 0.0:
        return 0.0
    return float(gradient @ direction) / along


def tangent(step, jacobian, direction):
    """``step`` (2 f,) less its part along ``direction`` (``H^-1 J``, (2 f,)) that changes the
    area to first order (``jacobian``, (2 f,)): a step along the constraint's tangent."""
    along = float(jacobian @ direction)
    if along <= 0.0:
        return step
    return step - direction * (float(jacobian @ step) / along)
