"""A two-grid preconditioner: the paper's constant matrix plus a Newton correction on a coarse
copy of the shape.

Refactoring the Newton matrix of :mod:`solver.hessian` on every solve breaks the paper's promise
that moving handles only changes right-hand sides, and above a few thousand points it fills in
too much to be affordable anyway. The paper's constant matrix ``K = A_f^T A_f`` (equation 9) factors
once, and it settles local detail (high frequencies) in a few iterations, but it treats turning
an edge as stiff, so the smooth, large-scale turns of whole limbs (low frequencies) crawl.

A coarse copy of the shape (a few hundred points; see ``solver.deformer``) spans exactly those
smooth motions: its binding ``P`` carries a coarse displacement to every fine
point, piecewise linearly. The Galerkin matrix ``P^T H P`` of the fine Newton matrix ``H`` is
small, so refactoring it costs what a Newton step on a paper-size shape costs, and a correction
through it turns limbs as Newton does, measured against the fine graph's own energy.

The two are combined as a cycle: a coarse correction, then a solve with ``K`` on what it left,
which L-BFGS uses as its initial inverse Hessian just as it uses a Newton factor on small graphs.
The cycle's error propagation is ``E = (I - K^-1 H)(I - P H_c^-1 P^T H)``: a projection that is
orthogonal in ``H``'s inner product times a map whose ``H``-norm is below 1, because ``H <= K``
(:mod:`solver.hessian` clamps every softening below 1). So ``||E||_H < 1``, and for any gradient
``g = H e`` the direction satisfies ``g^T M g = e^T H e - e^T H E e > 0``: the cycle is not
symmetric, but it always gives a descent direction, and BFGS updates keep that property.
"""

from __future__ import annotations

import numpy as np
import qdldl
from scipy.sparse import block_diag, coo_matrix, csc_matrix

from .hessian import Hessian, PaperMatrix

__all__ = ["TwoGrid"]

# Keeps the coarse matrix definite where the fine free points hardly move a coarse point.
_REGULARISATION = 1e-10
# Fine matrix entries handled at once while building the Galerkin map.
_CHUNK = 20000


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

    Notes
    -----
    The fold penalty's terms stay out: their curvature is not below ``K``'s, so with them the
    cycle could lose definiteness. L-BFGS learns that curvature instead.
    """

    def __init__(self, energy, free, prolongation):
        self._smoother = PaperMatrix(energy, free)
        self._newton = Hessian(energy, free, upper=False)  # the whole matrix, never factored
        prolongation = prolongation.tocsc()
        reached = np.flatnonzero(np.asarray(abs(prolongation).sum(axis=0)).ravel() > 0.0)
        columns = prolongation[:, reached]
        self._up = block_diag([columns, columns], format="csr")
        self._down = self._up.T.tocsr()
        self._galerkin, self._coarse_upper, self._diagonal_slots = _galerkin_map(
            self._newton.pattern, self._up)
        self._full = None
        self._factor = None

    def factorize(self, rows, fold_terms=None, fit=None):
        """Rebuild the coarse correction from the fine Newton matrix at the pose with
        ``A V = rows`` ((2, r)); arguments as for :meth:`Hessian.matrix`."""
        self._full = self._newton.matrix(rows, fold_terms, fit)
        values = self._coarse_upper.data
        values[:] = self._galerkin @ self._full.data
        diagonal = self._diagonal_slots
        values[diagonal] += _REGULARISATION * values[diagonal].max()
        if self._factor is None:
            self._factor = qdldl.Solver(self._coarse_upper, upper=True)
        else:
            self._factor.update(self._coarse_upper, upper=True)

    def _coarse_correction(self, residual):
        return self._up @ self._factor.solve(self._down @ residual)

    def solve(self, rhs):
        """Apply the two-grid cycle to ``rhs`` ((2 f,), stacked); returns (2 f,).

        A coarse correction, then one solve with ``K`` on what it left. A second coarse
        correction after the ``K`` solve (the symmetric cycle) took the same iterations on every
        benchmark drag at the cost of one more product with the fine matrix and one more coarse
        solve.
        """
        x = self._coarse_correction(rhs)
        x += self._smoother.solve(rhs - self._full @ x)
        return x


def _galerkin_map(fine, up):
    """The linear map from the fine matrix's values to the coarse upper triangle's.

    ``P^T H P`` with ``P = up`` (at most a few entries per row) is linear in ``H``'s values,
    with a sparsity that never changes; as one sparse matrix it turns a refresh into a mat-vec.

    Parameters
    ----------
    fine : (m, m) scipy.sparse.csc_matrix
        The whole fine matrix's pattern; the map reads its ``data`` in this order.
    up : (m, c) scipy.sparse matrix

    Returns
    -------
    galerkin : (s, nnz) scipy.sparse.csr_matrix
        Coarse upper-triangle values (csc order) from the fine ones.
    coarse_upper : (c, c) scipy.sparse.csc_matrix
        The coarse upper triangle, values to be filled in.
    diagonal_slots : (c,) int ndarray
        Positions of its diagonal in ``coarse_upper.data``.
    """
    fine = fine.tocoo()
    up = up.tocsr()
    count = up.shape[1]
    # Each row of P padded to the same width (zero weights where shorter).
    per_row = np.diff(up.indptr)
    width = max(int(per_row.max(initial=0)), 1)
    owner = np.repeat(np.arange(up.shape[0]), per_row)
    place = np.arange(up.nnz) - up.indptr[owner]
    index = np.zeros((up.shape[0], width), dtype=np.int64)
    weight = np.zeros((up.shape[0], width))
    index[owner, place], weight[owner, place] = up.indices, up.data
    # Entry (i, j) of H with value h adds h P_i^T P_j to P^T H P; the coarse upper triangle keeps
    # the part with row <= column. Built in chunks of entries to bound the memory used.
    keys, weights, entries = [], [], []
    for first in range(0, fine.nnz, _CHUNK):
        chunk = np.arange(first, min(first + _CHUNK, fine.nnz))
        i, j = fine.row[chunk], fine.col[chunk]
        shape = (len(chunk), width, width)
        a = np.broadcast_to(index[i][:, :, None], shape).ravel()
        b = np.broadcast_to(index[j][:, None, :], shape).ravel()
        w = (weight[i][:, :, None] * weight[j][:, None, :]).ravel()
        entry = np.broadcast_to(chunk[:, None, None], shape).ravel()
        keep = (w != 0.0) & (a <= b)
        keys.append(b[keep] * count + a[keep])           # (column, row): csc order
        weights.append(w[keep])
        entries.append(entry[keep])
    keys, weights, entries = np.concatenate(keys), np.concatenate(weights), np.concatenate(entries)
    diagonal_keys = np.arange(count, dtype=np.int64) * (count + 1)
    slots = np.union1d(keys, diagonal_keys)
    galerkin = coo_matrix((weights, (np.searchsorted(slots, keys), entries)),
                          shape=(len(slots), fine.nnz)).tocsr()
    galerkin.sum_duplicates()
    columns, rows = np.divmod(slots, count)
    indptr = np.searchsorted(columns, np.arange(count + 1))
    coarse_upper = csc_matrix((np.zeros(len(slots)), rows, indptr), shape=(count, count))
    return galerkin, coarse_upper, np.searchsorted(slots, diagonal_keys)
