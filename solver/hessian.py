"""The Hessian of the deformation energy on the free points, with a fixed sparsity pattern.

``E(V) = ||A V - b(V)||^2`` has Hessian ``2 A^T (I - db/d(AV)) A``. ``db/d(AV)`` is block
diagonal and each block is rank one:

* an inner edge with current vector ``d`` and rest length ``l0``: ``(l0 / |d|) v v^T`` with ``v``
  the unit normal of ``d``: turning an edge costs nothing, stretching it does;
* a boundary vertex's three curve rows with rest rows ``t_k`` and fitted rotation ``R``:
  ``q q^T / N`` with ``q_k = R J t_k`` (``J`` the quarter turn) and ``N`` the Procrustes norm.

So ``H = [K 0; 0 K] - sum_k c_k u_k u_k^T`` on the stacked free coordinates ``[x; y]``, with
``u_k = A^T w_k`` touching two points (edges) or three (curve groups). Each term's block
``I - c w w^T`` has the eigenvalue ``1 - c`` along ``w`` (1 elsewhere); ``c > 1`` (a compressed
edge, a squeezed curve group) makes it negative. :meth:`Hessian.matrix` offers three ways with
those terms (``filtering``):

* ``"exact"``: ``c`` as it is, the true Hessian (halved), positive definite near a minimum
  and often indefinite away from one;
* ``"absolute"``: the eigenvalue replaced by its absolute value (Chen et al. 2024, "Stabler
  Neo-Hookean simulation: absolute eigenvalue filtering for projected Newton"), bounded below
  by ``CLAMP``: positive definite at every pose, and a compressed term keeps the curvature it
  has rather than losing it;
* ``"clamp"``: ``c`` clamped below ``1 - CLAMP`` (projected Newton), which keeps ``H`` between
  ``CLAMP K`` and ``K``, as the two-grid's descent argument needs (:mod:`solver.two_grid`).

With the fold penalty of :mod:`solver.folds`, each squeezed triangle adds its Gauss-Newton term
``s g g^T`` (``g`` the gradient of its area): a third family with negative ``c_k``. The exact
matrix also takes the area's own curvature, weighted by how far the triangle is squeezed
(:class:`~solver.folds.FoldTerms`), without which Newton converges only linearly to a minimum
that leans on the penalty; the projected ones leave it out.

``K`` alone is what the paper's iteration (9) inverts: it treats turning an edge as stiff, which
is why free limbs converge so slowly with it. This matrix knows better, at the price of a
numeric refactorisation; the symbolic analysis is done once per handle set
(``benchmarks/refactor_free.py`` measures the ways around refactorising).
"""

from __future__ import annotations

import numpy as np
import qdldl
from scipy.sparse import block_diag, coo_matrix, csc_matrix, csr_matrix, triu

from .folds import AREA_HESSIAN

__all__ = ["Hessian", "NewtonMatrix", "PaperMatrix"]

# Filtered eigenvalues 1 - c_k >= CLAMP keep H >= CLAMP * [K 0; 0 K]: positive definite, however
# the shape turns.
CLAMP = 1e-3
FILTERINGS = ("clamp", "absolute", "exact")


def _filtered(ratio, filtering):
    """The coefficient ``c`` of a term whose exact one is ``ratio``, filtered (see the module
    docstring)."""
    if filtering == "exact":
        return ratio
    if filtering == "absolute":
        return 1.0 - np.maximum(np.abs(1.0 - ratio), CLAMP)
    return np.minimum(1.0 - CLAMP, ratio)


def _term_products(families, slot, f):
    """Where each low-rank term's products land in the Newton matrix.

    Each term contributes c u u^T on its points. The distinct products are laid out flat,
    family by family; a constant sparse matrix sums (with signs) the products that land on each
    stored entry, so assembly is one mat-vec. An edge's u is [a, -a, b, -b] on [x_i, x_j, y_i,
    y_j], so its 16 products are +-c a^2, +-c a b, +-c b^2 (3 stored); the other families store
    all k x k products.

    Returns
    -------
    rows, cols, flat_index : (q,) int ndarray
        Matrix entry (-1 where a point is not free) and flat product index of each product.
    signs : (q,) float ndarray
    """
    rows, cols, flat_index, signs = [], [], [], []
    offset = 0
    for family, points in enumerate(families):
        stacked = np.concatenate([slot[points], slot[points] + f], axis=1)
        stacked[np.concatenate([slot[points], slot[points]], axis=1) < 0] = -1
        count, k = stacked.shape
        rows.append(np.repeat(stacked, k, axis=1).ravel())
        cols.append(np.tile(stacked, (1, k)).ravel())
        if family == 0:
            axis, sign = np.array([0, 0, 1, 1]), np.array([1.0, -1.0, 1.0, -1.0])
            kind = (axis[:, None] + axis[None, :]).ravel()           # 0: a a, 1: a b, 2: b b
            flat_index.append(offset + 3 * np.repeat(np.arange(count), k * k) + np.tile(kind, count))
            signs.append(np.tile(np.outer(sign, sign).ravel(), count))
            offset += 3 * count
        else:
            flat_index.append(offset + np.arange(count * k * k))
            signs.append(np.ones(count * k * k))
            offset += count * k * k
    return tuple(np.concatenate(parts) for parts in (rows, cols, flat_index, signs))


def _pattern(stored, rows, cols, size):
    """The csc pattern holding ``stored``'s entries and ``(rows, cols)``, and a function giving
    the position in its values of entries ``(r, c)``."""
    # From coordinates only: adding sparse matrices is not safe here, as scipy's sum assumes
    # canonical (sorted, duplicate-free) operands and triu's are not.
    all_rows = np.concatenate([stored.row, rows]).astype(np.int64)
    all_cols = np.concatenate([stored.col, cols]).astype(np.int64)
    shape = coo_matrix((np.ones(len(all_rows)), (all_rows, all_cols)), shape=(size, size)).tocsc()
    shape.sum_duplicates()
    shape.sort_indices()
    keys = shape.indices.astype(np.int64) + size * np.repeat(np.arange(size, dtype=np.int64), np.diff(shape.indptr))
    return shape, lambda r, c: np.searchsorted(keys, r + size * c)


def _curve_group_factors(energy):
    """The pose-independent part of each curve group's low-rank vector.

    w_k = R J t_k / sqrt(T), with t_k the rest rows and J the quarter turn, and u = A^T w on the
    group's three points; R is the only part that changes with the pose.

    Returns
    -------
    total : (m,) ndarray
        T, each group's summed squared rest rows.
    base_x, base_y : (m, 3) ndarray
        The x and y parts of each corner's factor.
    """
    # (m, 3, 2): each vertex's laplacian, to-after and to-before rest rows
    rest = energy.curve_rest.reshape(3, -1, 2).transpose(1, 0, 2)
    turned = np.stack([-rest[..., 1], rest[..., 0]], axis=-1)
    total = np.einsum("gkc,gkc->g", rest, rest)
    scale = energy.curve_scale / np.sqrt(np.where(total > 0, total, 1.0))
    # u = A^T w: the group's rows of A are its kinds' factors times the unit stencils.
    kind = energy.curve_kind_scale
    lap, ahead, behind = kind[0] * turned[:, 0], kind[1] * turned[:, 1], kind[2] * turned[:, 2]
    corners = np.stack([lap - ahead - behind, -0.5 * lap + behind, -0.5 * lap + ahead], axis=1)
    corners *= scale[:, None, None]
    return total, np.ascontiguousarray(corners[..., 0]), np.ascontiguousarray(corners[..., 1])


class Hessian:
    """Projected Newton matrix of an :class:`~solver.energy.Energy` on the free points.

    Parameters
    ----------
    energy : solver.energy.Energy
    free : (f,) int ndarray
        Indices of the free points (not handles).
    triangles : (t, 3) int ndarray, optional
        With the fold penalty: its triangles, whose terms :meth:`matrix` then takes.
    upper : bool
        Keep the upper triangle (for factorising) or, with False, the whole symmetric matrix
        (for products with it).

    Notes
    -----
    Unknowns are stacked ``[x of free points; y of free points]`` (length ``2 f``).
    """

    follows_pose = True

    def __init__(self, energy, free, triangles=None, upper=True):
        self.energy = energy
        n = energy.n
        f = len(free)
        self.size = 2 * f
        slot = -np.ones(n, dtype=np.int64)
        slot[free] = np.arange(f)
        self._slot = slot

        matrix = energy.matrix.tocsc()
        free_columns = matrix[:, free]
        stiffness = (free_columns.T @ free_columns).tocsc()
        base = block_diag([stiffness, stiffness], format="csc")

        # Points each low-rank term touches, as (term, corner) arrays of point indices: inner
        # edges (e, 2), curve groups (m, 3: here, before, after) and, with the fold penalty
        # (solver.folds), triangles (t, 3).
        families = [energy.length_edges, energy.curve_points]
        if triangles is not None:
            families.append(triangles)
        rows, cols, flat_index, signs = _term_products(families, slot, f)
        keep = (rows >= 0) & (cols >= 0)
        if upper:
            keep &= rows <= cols
        stored = triu(base, format="coo") if upper else base.tocoo()
        shape, locate = _pattern(stored, rows[keep], cols[keep], 2 * f)
        self._base = np.bincount(locate(stored.row.astype(np.int64), stored.col.astype(np.int64)),
                                 weights=stored.data, minlength=shape.nnz)
        # Edges and curve groups are all active at every pose: one constant gather matrix sums
        # their products. Fold terms are active on the few squeezed triangles only, so each
        # triangle's 36 products have their slots in the stored values (-1: not stored), and
        # only the squeezed ones are scattered in (a gather over every triangle cost as much as
        # the rest of the assembly).
        count_edges, count_groups = len(families[0]), len(families[1])
        end = 3 * count_edges + 36 * count_groups
        paper_terms = flat_index < end
        take = keep & paper_terms
        self._gather = csr_matrix((signs[take], (locate(rows[take], cols[take]), flat_index[take])),
                                  shape=(shape.nnz, end))
        self._fold_slots = None
        if triangles is not None:
            folds = ~paper_terms  # laid out triangle after triangle, 36 products each
            slots = np.full(int(folds.sum()), -1, dtype=np.int64)
            slots[keep[folds]] = locate(rows[folds & keep], cols[folds & keep])
            self._fold_slots = slots.reshape(len(triangles), 36)
        self._stored = csc_matrix((self._base.copy(), shape.indices, shape.indptr), shape=shape.shape)
        self._factor = None
        # The products, laid out flat as the gather matrix reads them, written in place.
        self._products = np.zeros(end)
        self._edge_products = self._products[:3 * count_edges].reshape(count_edges, 3)
        self._group_products = self._products[3 * count_edges:end].reshape(count_groups, 6, 6)

        self._group_total, self._group_base_x, self._group_base_y = _curve_group_factors(energy)

    @property
    def pattern(self):
        """The stored sparsity (upper triangle or whole), ``(2 f, 2 f)`` csc: :meth:`matrix` only
        ever fills in the values of this one matrix, in this order."""
        return self._stored

    def matrix(self, rows, fold_terms=None, fit=None, filtering="clamp"):
        """The projected Hessian (halved) at the pose with ``A V = rows``: its upper triangle, or
        all of it for a Hessian made with ``upper=False``.

        Parameters
        ----------
        rows : (2, r) float ndarray
            ``A @ V``, coordinate-major.
        fold_terms : tuple, optional
            :meth:`solver.folds.FoldPenalty.terms` at the same pose, for a Hessian built with
            ``triangles``; None when no triangle is squeezed.
        fit : solver.energy.LocalFit, optional
            :meth:`~solver.energy.Energy.fit` at the same pose, if already made.
        filtering : {"clamp", "absolute", "exact"}
            What becomes of terms with negative curvature (module docstring). The fold
            penalty's terms are its Gauss-Newton terms in every case.

        Returns
        -------
        (2 f, 2 f) scipy.sparse.csc_matrix
            Reused by the next call: copy it to keep it.
        """
        if fit is None:
            fit = self.energy.fit(rows)
        products = self._products
        edges, groups = self._edge_products, self._group_products
        if filtering not in FILTERINGS:
            raise ValueError(f"filtering must be one of {FILTERINGS}, got {filtering!r}")
        c, a, b = self._edge_terms(rows, fit, filtering)
        ca = c * a
        np.multiply(ca, a, out=edges[:, 0])
        np.multiply(ca, b, out=edges[:, 1])
        np.multiply(c * b, b, out=edges[:, 2])
        c, u = self._group_terms(fit, filtering)
        np.multiply((c[:, None] * u)[:, :, None], u[:, None, :], out=groups)
        # The pattern never changes: overwrite the values of one matrix rather than building one.
        values = self._stored.data
        np.subtract(self._base, self._gather @ products, out=values)
        if self._fold_slots is not None and fold_terms is not None:
            c, u = fold_terms.coefficient, fold_terms.u
            squeezed = np.flatnonzero(c)
            if len(squeezed):
                u = u[squeezed]
                folds = (c[squeezed, None] * u)[:, :, None] * u[:, None, :]
                if filtering == "exact":
                    folds += fold_terms.bend[squeezed, None, None] * AREA_HESSIAN
                slots = self._fold_slots[squeezed].ravel()
                stored = slots >= 0
                np.subtract.at(values, slots[stored], folds.ravel()[stored])
        return self._stored

    def _edge_terms(self, rows, fit, filtering):
        """Coefficients (e,) and the scaled unit normal ``(a, b)`` of each edge: its u vector is
        ``[a, -a, b, -b]`` on ``[x_i, x_j, y_i, y_j]``."""
        energy = self.energy
        edge_x, edge_y = rows[0, energy.length_rows], rows[1, energy.length_rows]
        length = fit.edge_length
        inverse = np.divide(1.0, length, out=np.zeros_like(length), where=length > 0)
        coefficient = _filtered(energy.rest_length * inverse, filtering)  # ratio 0 where collapsed
        inverse *= energy.edge_scale
        return coefficient, -edge_y * inverse, edge_x * inverse

    def _group_terms(self, fit, filtering):
        """Coefficients (m,) and u vectors (m, 6) laid out as [x_here, x_before, x_after, y_...]."""
        cos, sin, norm = fit.cos, fit.sin, fit.procrustes
        ok = (norm > 0) & (self._group_total > 0)
        coefficient = np.where(ok, _filtered(self._group_total / np.where(ok, norm, 1.0), filtering), 0.0)
        # u is the fitted rotation applied to fixed combinations of the rest rows (see __init__).
        base_x, base_y = self._group_base_x, self._group_base_y
        u = np.empty((len(cos), 6))
        cos, sin = cos[:, None], sin[:, None]
        u[:, :3] = cos * base_x - sin * base_y
        u[:, 3:] = sin * base_x + cos * base_y
        return coefficient, u

    def factorize(self, rows, fold_terms=None, fit=None):
        """Factor the Hessian at the pose with ``A V = rows`` ((2, r)); the symbolic analysis
        is done only the first time. ``fold_terms`` and ``fit`` as for :meth:`matrix`."""
        self._refactor(self.matrix(rows, fold_terms, fit))

    def _refactor(self, upper):
        """Factor ``upper``, numeric values only after the first time; qdldl's RuntimeError on
        a zero pivot."""
        if self._factor is None:
            self._factor = qdldl.Solver(upper, upper=True)
        else:
            self._factor.update(upper, upper=True)

    def solve(self, rhs, forcing=0.0):
        """Solve with the last factor.

        Parameters
        ----------
        rhs : (2 f,) float ndarray
            Stacked ``[x of free points; y of free points]``.
        forcing : float
            Ignored: a factor solves exactly (to rounding). Taken for the interface that
            :class:`~solver.krylov.KrylovNewton` shares.

        Returns
        -------
        (2 f,) float64 ndarray
        """
        return self._factor.solve(rhs)


class NewtonMatrix(Hessian):
    """The matrix a Newton iteration steps with: the exact Hessian where it is positive definite,
    else the matrix halfway to its projection where that is, else the projection.

    Near a minimum the exact Hessian is positive definite and Newton converges quadratically.
    Away from a minimum the exact matrix is indefinite and its step may climb.
    :meth:`factorize` factorises the exact matrix at every iterate and reads its inertia from
    the ``L D L^T`` pivots (Sylvester's law). If any pivot is not positive it takes the matrix
    halfway to the projected one (``filtering="clamp"``): every compressed term keeps half its
    negative curvature, the fold penalty half its area curvature. If that is still indefinite,
    the projected matrix itself. All share one pattern and symbolic analysis.

    The projection drops the negative curvature of compressed terms (down to ``CLAMP`` times
    the paper's matrix) rather than flipping it as absolute-eigenvalue filtering does: the
    flipped terms made the matrix about twice as stiff as the energy along the steps (the
    energy fell about twice as much as the model predicted, step after step) and the steps
    short. The projection alone is still stiffer than the energy along the flat valleys of a
    swinging limb; the halfway matrix, where definite, follows them further. Measurements in
    ``docs/solver_options.md``.

    A :class:`~solver.preconditioner.NewtonSystem`.

    Attributes
    ----------
    exact : bool
        Whether the last factor is of the exact Hessian (then positive definite).
    """

    #: What the matrix is where the exact one is not positive definite (see :meth:`matrix`).
    fallback = "clamp"

    follows_pose = True

    def __init__(self, energy, free, triangles=None):
        super().__init__(energy, free, triangles)
        self.exact = False

    def factorize(self, rows, fold_terms=None, fit=None):
        """Factor at the pose with ``A V = rows`` ((2, r)); arguments as for :meth:`matrix`.

        The exact matrix is tried at every iterate, even after it was refused at the last: an
        indefinite matrix costs one factorisation more, while a positive definite one missed
        (the matrix turns definite in the last few iterations of a solve) costs iterations.
        """
        if fit is None:
            fit = self.energy.fit(rows)
        self.exact = self._definite(self.matrix(rows, fold_terms, fit, "exact"))
        if self.exact:
            return
        exact = self._stored.data.copy()
        matrix = self.matrix(rows, fold_terms, fit, self.fallback)  # the same matrix, refilled
        projected = matrix.data.copy()
        matrix.data[:] = 0.5 * (exact + projected)
        if self._definite(matrix):
            return
        matrix.data[:] = projected
        self._refactor(matrix)

    def _definite(self, upper):
        """Factor ``upper``; whether it is positive definite (singular is not)."""
        try:
            self._refactor(upper)
        except RuntimeError:  # a zero pivot
            self._factor = None
            return False
        return bool(np.all(self._factor.factors()[1] > 0.0))


class PaperMatrix:
    """``A_f^T A_f``, the paper's constant matrix of equation (9), factorised once.

    The same factor serves x and y. For large graphs the coupled Newton matrix fills in too much
    to refactor; this one never changes, so an iteration costs one back-substitution per
    coordinate, as in the paper. A :class:`~solver.preconditioner.Preconditioner`.
    """

    follows_pose = False

    def __init__(self, energy, free):
        columns = energy.matrix.tocsc()[:, free]
        stiffness = (columns.T @ columns).tocsc()
        self._factor = qdldl.Solver(triu(stiffness, format="csc"), upper=True)

    def factorize(self, rows, fold_terms=None, fit=None):
        """Nothing to do: the matrix does not depend on the pose."""

    def solve(self, rhs):
        """Solve for each coordinate; ``rhs`` and the result are stacked ``(2 f,)``."""
        half = len(rhs) // 2
        return np.concatenate([self._factor.solve(rhs[:half]), self._factor.solve(rhs[half:])])
