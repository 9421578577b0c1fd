"""A two-grid preconditioner for large graphs: the paper's constant matrix plus a coarse Newton
correction.

Above ``NEWTON_MAX_POINTS`` points the Newton matrix of :mod:`solver.hessian` fills in too much
to refactor on every solve. The paper's constant matrix ``K = A_f^T A_f`` (equation 9) factors
once, and it settles local detail (high frequencies) in a few iterations, but it treats turning
an edge as stiff, so the smooth, large-scale turns of whole limbs (low frequencies) crawl.

A coarse copy of the shape (a few hundred points, already built for the start pose) spans
exactly those smooth motions: its binding ``P`` carries a coarse displacement to every fine
point, piecewise linearly. The Galerkin matrix ``P^T H P`` of the fine Newton matrix ``H`` is
small, so refactoring it costs what a Newton step on a paper-size shape costs, and a correction
through it turns limbs as Newton does, measured against the fine graph's own energy.

The two are combined as a symmetric two-grid cycle (coarse correction, a solve with ``K``,
coarse correction again), a fixed symmetric positive definite operator between refreshes, which
L-BFGS uses as its initial inverse Hessian just as it uses a Newton factor on small graphs.
``H <= K`` (:mod:`solver.hessian` clamps every softening below 1), so ``K`` is a convergent
smoother and the cycle is positive definite.
"""

from __future__ import annotations

import numpy as np
import qdldl
from scipy.sparse import block_diag, coo_matrix, csc_matrix, identity, triu

from .hessian import Hessian, PaperMatrix

__all__ = ["TwoGrid"]

# Keeps the coarse matrix definite where the fine free points hardly move a coarse point.
_REGULARISATION = 1e-10


class TwoGrid:
    """Two-grid preconditioner on the stacked free coordinates ``[x; y]`` (length ``2 f``).

    Same interface as :class:`~solver.hessian.Hessian`: :meth:`factorize` refreshes the coarse
    correction at a pose (one numeric refactorisation of the small coarse matrix; the fine factor
    of ``K`` is never touched), :meth:`solve` applies the cycle.

    Parameters
    ----------
    energy : solver.energy.Energy
    free : (f,) int ndarray
        Indices of the free points.
    prolongation : (f, c) scipy.sparse matrix
        Weights carrying coarse point displacements to the free fine points (a
        :class:`~solver.binding.Binding`'s rows for them).
    triangles : (t, 3) int ndarray, optional
        The fine graph's triangles, when the fold penalty is on (see :class:`Hessian`).
    """

    def __init__(self, energy, free, prolongation, triangles=None):
        self._smoother = PaperMatrix(energy, free)
        self._newton = Hessian(energy, free, triangles)  # assembled, never factored
        prolongation = prolongation.tocsc()
        reached = np.flatnonzero(np.asarray(abs(prolongation).sum(axis=0)).ravel() > 0.0)
        columns = prolongation[:, reached]
        self._up = block_diag([columns, columns], format="csr")
        self._down = self._up.T.tocsr()
        self._upper = None           # fine Newton matrix, upper triangle (csc)
        self._diagonal = None
        self._pattern_keys = None    # the coarse matrix's fixed sparsity, upper triangle
        self._coarse_upper = None
        self._factor = None

    def factorize(self, rows, fold_terms=None, fit=None):
        """Rebuild the coarse correction from the fine Newton matrix at the pose with
        ``A V = rows`` ((2, r)); arguments as for :meth:`Hessian.matrix`."""
        upper = self._newton.matrix(rows, fold_terms, fit)
        self._upper, self._diagonal = upper, upper.diagonal()
        # P^T H P with H = U + U^T - D: half of it from U, then symmetrised.
        half = (self._down @ (upper @ self._up)).tocsr()
        coarse = half + half.T - self._down @ (self._up.multiply(self._diagonal[:, None])).tocsr()
        coarse = triu(coarse, format="coo")
        if self._pattern_keys is None:
            self._start_pattern(coarse)
        # Sparse products drop entries that happen to be 0.0; the factor's pattern must not move.
        n = self._coarse_upper.shape[0]
        keys = coarse.col.astype(np.int64) * n + coarse.row
        values = np.zeros(len(self._pattern_keys))
        values[np.searchsorted(self._pattern_keys, keys)] = coarse.data
        values[self._diagonal_slots] += _REGULARISATION * values[self._diagonal_slots].max()
        self._coarse_upper.data[:] = values
        if self._factor is None:
            self._factor = qdldl.Solver(self._coarse_upper, upper=True)
        else:
            self._factor.update(self._coarse_upper, upper=True)

    def _start_pattern(self, coarse):
        """Fix the coarse matrix's upper-triangle pattern: every entry the products can reach."""
        n = coarse.shape[0]
        structure = lambda m: m.__class__((np.ones(m.nnz), m.indices, m.indptr), shape=m.shape)
        reach = structure(self._down) @ structure(self._upper) @ structure(self._up)
        reach = triu(reach + reach.T + identity(n), format="csc")
        reach.sort_indices()
        self._coarse_upper = csc_matrix((np.zeros(reach.nnz), reach.indices, reach.indptr), shape=(n, n))
        columns = np.repeat(np.arange(n, dtype=np.int64), np.diff(reach.indptr))
        self._pattern_keys = columns * n + reach.indices
        self._diagonal_slots = np.searchsorted(self._pattern_keys, np.arange(n, dtype=np.int64) * (n + 1))

    def _times_newton(self, x):
        upper = self._upper
        return upper @ x + upper.T @ x - self._diagonal * x

    def _coarse_correction(self, residual):
        return self._up @ self._factor.solve(self._down @ residual)

    def solve(self, rhs):
        """Apply the two-grid cycle to ``rhs`` ((2 f,), stacked); returns (2 f,)."""
        x = self._coarse_correction(rhs)
        x += self._smoother.solve(rhs - self._times_newton(x))
        x += self._coarse_correction(rhs - self._times_newton(x))
        return x
