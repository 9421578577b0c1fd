"""The matrices a solve steps with, and the choice among them (:func:`choose`).

Every one stands for the energy's Hessian on the stacked free coordinates ``[x; y]``.
:func:`solver.optimizer.newton` solves with one at every iterate (:class:`NewtonSystem`):

- :class:`~solver.hessian.NewtonMatrix`: the Newton matrix of the whole graph, one numeric
  refactorisation per iterate (graphs up to ``Options.newton_max_points``, ``newton=True``);
- :class:`~solver.krylov.KrylovNewton`: the exact Hessian, its system solved by conjugate
  gradients over the two-grid cycle (larger graphs).

L-BFGS (:func:`solver.optimizer.minimise`) uses one as its initial inverse Hessian
(:class:`Preconditioner`, chosen by :func:`choose`):

- :class:`~solver.two_grid.TwoGrid`: the paper's constant matrix, factorised once, plus a
  Newton correction on a coarse copy of the shape (large graphs with the area constraint, up
  to ``Options.two_grid_max_points``);
- :class:`~solver.hessian.PaperMatrix`: the paper's constant matrix alone (``newton=False``,
  and larger graphs).
"""

from __future__ import annotations

from typing import Protocol

from .hessian import NewtonMatrix, PaperMatrix
from .krylov import KrylovNewton
from .two_grid import TwoGrid

__all__ = ["NewtonSystem", "Preconditioner", "choose"]


class NewtonSystem(Protocol):
    """What Newton's method (:func:`solver.optimizer.newton`) needs of the matrix it steps with."""

    #: True: :meth:`factorize` is called at every iterate.
    follows_pose: bool

    #: Whether the last :meth:`solve` used the exact Hessian and met only positive curvature
    #: (a definite factor, or conjugate gradients that never turned back): only such a step
    #: says how far the minimum is, so only a short one of these stops a solve.
    exact: bool

    def factorize(self, rows, fold_terms=None, fit=None):
        """Take the Hessian at the pose with ``A V = rows`` ((2, r)); ``fold_terms`` and ``fit``
        as for :meth:`Preconditioner.factorize`."""

    def solve(self, rhs, forcing=0.0):
        """The Newton step's system: ``H x = rhs`` ((2 f,)) to a relative residual ``forcing``
        (a factor solves it exactly); returns ``x`` (2 f,)."""


class Preconditioner(Protocol):
    """What L-BFGS (:func:`solver.optimizer.minimise`) needs of its initial inverse Hessian."""

    #: Whether :meth:`factorize` depends on the pose (False: the optimiser never refreshes it).
    follows_pose: bool

    def factorize(self, rows, fold_terms=None, fit=None):
        """Refresh at the pose with ``A V = rows`` ((2, r)); ``fold_terms`` from
        :meth:`solver.folds.FoldPenalty.terms` and ``fit`` from :meth:`solver.energy.Energy.fit`
        at the same pose, when known."""

    def solve(self, rhs):
        """Apply the approximate inverse Hessian to ``rhs`` ((2 f,)); returns (2 f,)."""


def choose(energy, free, triangles, newton, options, coarse, preserve_area=False):
    """The matrix a deformer's solves step with, and whether they take Newton steps with it.

    Newton's method on a factorised :class:`~solver.hessian.NewtonMatrix` for small graphs
    (up to ``options.newton_max_points``), any graph without a coarse copy and ``newton=True``;
    on larger graphs Newton's method with CG over the two-grid (:class:`~solver.krylov.KrylovNewton`),
    or L-BFGS over the two-grid where the area constraint's projections need a factor; above
    ``options.two_grid_max_points``, and with ``newton=False``, L-BFGS over the paper's matrix.

    Parameters
    ----------
    energy : solver.energy.Energy
    free : (f,) int ndarray
    triangles : (t, 3) int ndarray or None
        The graph's triangles with the fold penalty, else None.
    newton : bool or None
        As :class:`solver.Deformer` takes it.
    options : solver.Options
    coarse : tuple or None
        ``(coarse graph, binding of the fine points to it)`` for a two-grid, or None.
    preserve_area : bool
        Whether solves hold the area constraint.

    Returns
    -------
    matrix : NewtonSystem or Preconditioner
    newton_steps : bool
        True for :func:`solver.optimizer.newton`, False for L-BFGS (:func:`solver.optimizer.minimise`).
    """
    if newton is True or (newton is None and (energy.n <= options.newton_max_points or coarse is None)):
        return NewtonMatrix(energy, free, triangles), True
    if newton is None and energy.n <= options.two_grid_max_points:
        prolongation = coarse[1].weights[free]
        if not preserve_area:
            return KrylovNewton(energy, free, prolongation, triangles), True
        return TwoGrid(energy, free, prolongation, triangles, options.max_fold_terms), False
    return PaperMatrix(energy, free), False
