"""Newton steps for graphs too large to refactorise the Newton matrix: conjugate gradients on
the exact Hessian, preconditioned by the two-grid cycle.

Above ``Options.newton_max_points`` the Newton matrix fills in too much to factorise at every
iterate, and L-BFGS over the two-grid preconditioner needed a schedule of refreshes, tuned on
named drags, to turn free limbs. :class:`KrylovNewton` keeps Newton's method instead and only
solves its system inexactly (a truncated Newton method, Nocedal and Wright, algorithm 7.1):

* the matrix is the exact Hessian (halved) of the energy and the fold penalty at the iterate,
  assembled into a fixed pattern and used only in products, never factorised;
* conjugate gradients stop once the residual is below ``forcing`` times the gradient; the
  optimiser passes ``forcing = min(1/2, sqrt(|g| / |g_0|))`` (Eisenstat and Walker), so steps far
  from the minimum are cheap and steps near it converge superlinearly;
* where the exact Hessian has negative curvature along a search direction (away from a minimum),
  CG stops and returns what it has, a descent direction: the last iterate, or the preconditioned
  gradient at the first. The line search then takes over, as with a projected matrix;
* the preconditioner is the two-grid cycle of :mod:`solver.two_grid` in its symmetric form, as
  CG needs, refreshed at every iterate (one small coarse refactorisation; the fine factor of the
  paper's matrix is never touched).

Measurements (random drags at 5,000 points, against L-BFGS with refreshes) are in
``docs/solver_options.md``.
"""

from __future__ import annotations

import numpy as np

from .hessian import Hessian
from .two_grid import TwoGrid

__all__ = ["KrylovNewton"]


class KrylovNewton:
    """The Newton system of a large graph, solved by preconditioned conjugate gradients.

    A :class:`~solver.preconditioner.NewtonSystem`: :meth:`factorize` at an iterate,
    :meth:`solve` for the step, :attr:`exact`.

    Parameters
    ----------
    energy : solver.energy.Energy
    free : (f,) int ndarray
    prolongation : (f, c) scipy.sparse matrix
        The coarse copy's weights for the free points (see :class:`~solver.two_grid.TwoGrid`).
    triangles : (t, 3) int ndarray, optional
        With the fold penalty: its triangles.

    Attributes
    ----------
    exact : bool
        Whether the last :meth:`solve` met only positive curvature: its step is then the Newton
        step to within the forcing term, and a short one means a minimum is near.
    cg_iterations : int
        CG iterations of the last :meth:`solve`.
    """

    follows_pose = True

    def __init__(self, energy, free, prolongation, triangles=None):
        self._hessian = Hessian(energy, free, triangles, upper=False)
        # The fold terms stay out of the smoother (max_fold_terms=0): CG needs a symmetric
        # positive definite preconditioner, not one above the matrix, and each term would cost
        # a back-substitution per refresh.
        self._two_grid = TwoGrid(energy, free, prolongation, triangles, max_fold_terms=0)
        self._matrix = None
        self.exact = False
        self.cg_iterations = 0

    def factorize(self, rows, fold_terms=None, fit=None):
        """Take the exact Hessian at the pose with ``A V = rows`` ((2, r)) and refresh the
        preconditioner there; arguments as for :meth:`solver.hessian.Hessian.matrix`."""
        if fit is None:
            fit = self._hessian.energy.fit(rows)
        self._matrix = self._hessian.matrix(rows, fold_terms, fit, filtering="exact")
        self._two_grid.factorize(rows, fold_terms, fit)

    def solve(self, rhs, forcing=0.0):
        """An approximate solution of ``H x = rhs`` ((2 f,)) by preconditioned CG, stopped when
        the residual falls below ``forcing * |rhs|`` or the curvature along a direction is not
        positive (then :attr:`exact` is False, and ``x`` still has ``rhs^T x > 0``)."""
        matrix, precondition = self._matrix, self._two_grid.symmetric_solve
        x = np.zeros_like(rhs)
        residual = rhs.copy()
        z = precondition(residual)
        direction = z.copy()
        rz = float(residual @ z)
        bound = forcing * float(np.linalg.norm(rhs))
        self.exact = True
        # In exact arithmetic CG ends within len(rhs) iterations; the bound only guards rounding.
        for self.cg_iterations in range(1, len(rhs) + 1):
            product = matrix @ direction
            curvature = float(direction @ product)
            if curvature <= 0.0:
                self.exact = False
                return direction if self.cg_iterations == 1 else x
            step = rz / curvature
            x += step * direction
            residual -= step * product
            if float(np.linalg.norm(residual)) <= bound:
                break
            z = precondition(residual)
            rz, previous = float(residual @ z), rz
            direction = z + (rz / previous) * direction
        return x
