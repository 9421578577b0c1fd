"""The deformation energy of the paper, equation (6), written as ``||A V - b(V)||^2``.

Rows of ``A`` come in three blocks, each with its own weight (the square root of the user's
weight multiplies the rows, so the weight multiplies the squared term):

* ``laplacian``: the curve Laplacian, equations (1)-(2), one row per boundary vertex, plus the
  two curve edges at that vertex. The paper fits the transform T_i of section 4.2 to those two
  edges as a general 2x2 matrix; fitted that way it maps both rest edges exactly onto the current
  ones, so T_i delta_i^0 equals the current Laplacian and the term does nothing (and D_i is
  singular on straight runs). We constrain T_i to a rotation, as its reference [15] does, and fit
  it to the same three rows the energy measures, so the local step minimises the energy exactly.
* ``mvc``: mean value coordinates of interior points, equation (3); the target is zero.
* ``edge``: edge lengths, equations (4)-(5), for the edges not on the boundary (E_g); the target
  ``l0 * d / |d|`` is the nearest vector of rest length, again an exact minimiser.

The paper's sums are not density-invariant: with point spacing ``h`` an edge row measures
``h`` times a strain, a mean value row and a curve Laplacian row a second difference, about
``h^2`` times a curvature. Summed over the ``~1/h^2`` interior rows and ``~1/h`` boundary rows,
the edge terms approximate an area integral of strain squared whatever ``h``, the curve edge
rows a line integral times ``h``, the mean value rows an area integral times ``h^2`` and the
Laplacian rows ``h^2`` to ``h^3`` (measured, see ``DENSITY_EXPONENTS``). At 5,000 points the
terms that resist bending have all but vanished beside the edge terms. With a
``reference_spacing`` each kind of row is weighted by ``(reference_spacing / graph.spacing)``
to its exponent, so a graph denser than the reference minimises the reference's energy
sampled more finely; at the reference spacing every weight is exactly 1.

Because every target is the exact minimiser of its own residual, ``E(V) = min_b ||A V - b||^2``
over admissible targets, and its gradient is ``2 A^T (A V - b(V))`` (envelope theorem). That is
what lets :mod:`solver.optimizer` take Newton and quasi-Newton steps with an energy that never rises.

The solver's hot path keeps rows coordinate-major, shape ``(2, r)``: ``rows[0]`` holds the x
parts of ``A V``, ``rows[1]`` the y parts, so x and y stack into one flat vector without copies.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import NamedTuple

import numpy as np
from scipy.sparse import coo_matrix, diags, vstack

from .wording import by_count

__all__ = ["DEFAULT_WEIGHTS", "DENSITY_EXPONENTS", "Energy", "LocalFit", "UncoveredPoints", "mean_value_weights",
           "similarity_rows", "uncovered_points"]

# Read-only: a module-level dict would be state shared by every caller.
DEFAULT_WEIGHTS = MappingProxyType({"laplacian": 1.0, "mvc": 1.0, "edge": 1.0})

# Powers of (reference spacing / graph spacing) on the squared rows of each kind, so each
# kind's sum approximates one continuum quantity at any density. Measured by applying smooth
# bends and waves to graphs of 1, 1/2 and 1/3 of the default spacing (star, glyph g, octopus,
# a bar): edge rows' sums stayed within 10% (exponent 0), curve edge rows' fell as h^1.0,
# mean value rows' as h^1.8-1.95; curve Laplacian rows' as h^2.1-2.4, not the h^3 a smooth
# curve's second differences give, because on polygon outlines their energy sits at the
# corners (a fixed number of rows whose residual is a first difference, ~h), and on straight
# runs as h^3. See docs/solver_options.md.
DENSITY_EXPONENTS = MappingProxyType({"laplacian": 2.0, "curve_edge": 1.0, "mvc": 2.0, "edge": 0.0})

# Spacings within this relative difference of the reference count as the reference.
_SAME_SPACING = 1e-3

# Angles are kept inside (0, pi) by this margin: tan(alpha / 2) blows up as alpha nears pi.
_ANGLE_MARGIN = 1e-6


class LocalFit(NamedTuple):
    """What the local step fitted at one pose; the Newton matrix is built from the same fit.

    Attributes
    ----------
    cos, sin : (m,) float64 ndarray
        Each boundary vertex's fitted rotation (identity where undefined).
    procrustes : (m,) float64 ndarray
        ``|sum_k t_k . d_k, sum_k t_k x d_k|`` over its three curve rows: rest rows ``t_k``,
        current rows ``d_k``.
    edge_length : (e,) float64 ndarray
        Current length of each inner edge.
    """

    cos: np.ndarray
    sin: np.ndarray
    procrustes: np.ndarray
    edge_length: np.ndarray


def mean_value_weights(points, centres, neighbours, row_starts):
    """Mean value coordinates of each centre with respect to its neighbours (Floater 2003).

    Parameters
    ----------
    points : (n, 2) float ndarray
    centres : (c,) int ndarray
        The points whose coordinates are wanted.
    neighbours : (e,) int ndarray
        Neighbour indices, grouped by centre (CSR order).
    row_starts : (c + 1,) int ndarray
        ``neighbours[row_starts[k]:row_starts[k+1]]`` are the neighbours of ``centres[k]``.

    Returns
    -------
    (e,) float64 ndarray
        Weights in the order of ``neighbours``; each centre's weights sum to 1 and reproduce it:
        ``points[centre] == sum(w_j * points[j])`` for a point inside its neighbours' polygon.
    """
    counts = np.diff(row_starts)
    owner = np.repeat(np.arange(len(centres)), counts)
    offset = points[neighbours] - points[centres[owner]]
    theta = np.arctan2(offset[:, 1], offset[:, 0])
    order = np.lexsort((theta, owner))  # counter-clockwise within each centre
    sorted_theta = theta[order]
    position = np.arange(len(order))
    following = position + 1
    last = row_starts[1:] - 1
    following[last] = row_starts[:-1]
    # alpha[k]: angle at the centre between sorted neighbours k and k+1.
    alpha = np.mod(sorted_theta[following] - sorted_theta, 2.0 * np.pi)
    alpha = np.clip(alpha, _ANGLE_MARGIN, np.pi - _ANGLE_MARGIN)
    half_tan = np.tan(0.5 * alpha)
    preceding = position - 1
    preceding[row_starts[:-1]] = last
    length = np.maximum(np.linalg.norm(offset[order], axis=1), 1e-300)
    sorted_weights = (half_tan[preceding] + half_tan) / length
    weights = np.empty_like(sorted_weights)
    weights[order] = sorted_weights
    totals = np.bincount(owner, weights=weights, minlength=len(centres))
    return weights / totals[owner]


class Energy:
    """Rows of ``A``, their rest targets, and the local step that gives ``b(V)``.

    Parameters
    ----------
    graph : solver.Graph
    weights : dict, optional
        Weights of the ``"laplacian"``, ``"mvc"`` and ``"edge"`` terms (default 1 each).
    stiffness : (n,) array_like, optional
        A factor (> 0, default 1) on every term of each point: a boundary vertex's curve rows,
        an interior point's mean value row, and an edge's length row by the mean of its two
        points' factors. Above 1 the region bends and stretches less (a starch pin).
    reference_spacing : float, optional
        Normalise for density: each kind of row is weighted by
        ``(reference_spacing / graph.spacing) ** DENSITY_EXPONENTS[kind]`` (module docstring),
        so the energy is the same functional at any density; equal weights at
        ``graph.spacing == reference_spacing``. None (default): the paper's sums as they are.

    Attributes
    ----------
    matrix : (r, n) scipy.sparse.csr_matrix
        ``A``, weighted.
    curve_scale : float or (m,) float64 ndarray
        Each boundary vertex's factor on its three curve rows (the Laplacian weight's root
        times its stiffness's).
    curve_kind_scale : (3,) float64 ndarray
        A further factor on the Laplacian, to-after and to-before rows (the density
        normalisation; ones without it).
    density_normalised : bool
        Whether the density normalisation changed any weight (False without it and at the
        reference spacing).
    spacing_ratio : float
        ``reference_spacing / graph.spacing``: 1 without the normalisation and at the
        reference spacing.
    """

    def __init__(self, graph, weights=None, stiffness=None, reference_spacing=None):
        self.weights = dict(DEFAULT_WEIGHTS)
        if weights is not None and not isinstance(weights, dict):
            raise ValueError(f"weights must be a dict of the terms {sorted(DEFAULT_WEIGHTS)}, got {weights!r}")
        for key, value in (weights or {}).items():
            if key not in DEFAULT_WEIGHTS:
                raise ValueError(f"unknown energy term {key!r}; the terms are {sorted(DEFAULT_WEIGHTS)}")
            value = float(value)
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"weight of {key!r} must be a finite number >= 0, got {value}")
            self.weights[key] = value
        if sum(self.weights.values()) == 0:
            raise ValueError("all energy weights are zero")
        n = graph.n
        rest = graph.points

        curve, self.curve_points = self._curve_rows(graph)
        mvc = self._mean_value_rows(graph)
        lengths, self.length_edges = self._length_rows(graph)
        # Which points each term has rows on, whatever its weight (see UncoveredPoints).
        self.term_points = {"laplacian": np.unique(self.curve_points), "mvc": np.unique(mvc.col),
                            "edge": np.unique(self.length_edges)}
        scale = {key: np.sqrt(value) for key, value in self.weights.items()}
        self.spacing_ratio = self._spacing_ratio(graph, reference_spacing)
        density = {kind: float(self.spacing_ratio ** (0.5 * power)) for kind, power in DENSITY_EXPONENTS.items()}
        self.density_normalised = self.spacing_ratio != 1.0
        scale["mvc"] *= density["mvc"]
        scale["edge"] *= density["edge"]
        self.curve_kind_scale = np.array([density["laplacian"], density["curve_edge"], density["curve_edge"]])
        factor = self._stiffness(graph, stiffness)
        # Per row: a term's weight times its points' stiffness (a scalar when all are 1).
        self.curve_scale = scale["laplacian"] * (np.sqrt(factor[self.curve_points[:, 0]])
                                                 if stiffness is not None else 1.0)
        self.edge_scale = scale["edge"] * (np.sqrt(factor[self.length_edges].mean(axis=1))
                                           if stiffness is not None else 1.0)
        mvc_scale = scale["mvc"] * (np.sqrt(factor[graph.interior]) if stiffness is not None else 1.0)
        m = len(self.curve_points)
        curve_row_scale = (self.curve_kind_scale[:, None] * np.broadcast_to(self.curve_scale, m)).ravel()
        blocks = [diags(curve_row_scale) @ curve,
                  diags(np.broadcast_to(mvc_scale, mvc.shape[0])) @ mvc,
                  diags(np.broadcast_to(self.edge_scale, lengths.shape[0])) @ lengths]
        self.matrix = vstack([b.tocsr() for b in blocks], format="csr")
        sizes = [b.shape[0] for b in blocks]
        self.curve_rows = slice(0, sizes[0])
        self.length_rows = slice(sizes[0] + sizes[1], sum(sizes))

        rest_rows = self.matrix @ rest
        self.curve_rest = rest_rows[self.curve_rows].copy()
        # (3, m): row k of each, for every boundary vertex (see _curve_rows).
        self._curve_rest_x = np.ascontiguousarray(self.curve_rest[:, 0]).reshape(3, -1)
        self._curve_rest_y = np.ascontiguousarray(self.curve_rest[:, 1]).reshape(3, -1)
        rest_edge = rest_rows[self.length_rows]
        self.rest_length = np.linalg.norm(rest_edge, axis=1)
        self._rest_direction = np.ascontiguousarray(
            (rest_edge / np.maximum(self.rest_length, 1e-300)[:, None]).T)
        self.n = n

    @staticmethod
    def _spacing_ratio(graph, reference_spacing):
        """``reference_spacing / graph.spacing``, the base of the density normalisation's
        factors: exactly 1 without it or at the reference spacing."""
        if reference_spacing is None:
            return 1.0
        reference_spacing = float(reference_spacing)
        if not np.isfinite(reference_spacing) or reference_spacing <= 0:
            raise ValueError(f"reference_spacing must be a positive number, got {reference_spacing}")
        ratio = reference_spacing / graph.spacing
        # build_graph's default spacing comes from the area of the rings it was given, the
        # reference from the graph's own loops (near-duplicate vertices merged, rounding): a
        # graph at the default spacing keeps the paper's rows bit for bit.
        return 1.0 if abs(ratio - 1.0) <= _SAME_SPACING else float(ratio)

    @staticmethod
    def _stiffness(graph, stiffness):
        if stiffness is None:
            return np.ones(graph.n)
        factor = np.asarray(stiffness, dtype=np.float64).reshape(-1)
        if factor.shape != (graph.n,):
            raise ValueError(f"stiffness must have one value per graph point ({graph.n}), got {factor.shape}")
        if not np.all(np.isfinite(factor)) or factor.min() <= 0:
            raise ValueError("stiffness must be finite and > 0 at every point")
        return factor

    @staticmethod
    def _curve_rows(graph):
        """Curve Laplacian (eq. 1) and the two curve edges at each boundary vertex (sec. 4.2).

        Rows are laid out kind by kind over all ``m`` boundary vertices: Laplacian rows first,
        then the edges to the next vertex, then the edges to the previous one, so a vertex's
        three rows are ``g, m + g, 2 m + g`` and ``(3, m)`` views group them with contiguous
        rows (sums over the three are then plain adds, not reductions over a short axis).
        """
        corners = np.concatenate([np.stack([loop, np.roll(loop, 1), np.roll(loop, -1)], axis=1)
                                  for loop in graph.boundary_loops])
        here, before, after = corners.T
        m = len(corners)
        r = np.arange(m)
        ones = np.ones(m)
        # Laplacian row: v_i - (v_{i-1} + v_{i+1}) / 2; edge rows: v_{i+1} - v_i and v_{i-1} - v_i
        rows = [r, r, r, m + r, m + r, 2 * m + r, 2 * m + r]
        cols = [here, before, after, after, here, before, here]
        vals = [ones, -0.5 * ones, -0.5 * ones, ones, -ones, ones, -ones]
        matrix = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                            shape=(3 * m, graph.n))
        return matrix, corners

    @staticmethod
    def _mean_value_rows(graph):
        """v_i - sum_j w_ij v_j for interior points (eq. 3)."""
        centres = graph.interior
        if len(centres) == 0:
            return coo_matrix((0, graph.n))
        adjacency = graph.adjacency()[centres]
        neighbours = adjacency.indices.astype(np.int64)
        starts = adjacency.indptr.astype(np.int64)
        weights = mean_value_weights(graph.points, centres, neighbours, starts)
        k = len(centres)
        owner = np.repeat(np.arange(k), np.diff(starts))
        rows = np.concatenate([np.arange(k), owner])
        cols = np.concatenate([centres, neighbours])
        vals = np.concatenate([np.ones(k), -weights])
        return coo_matrix((vals, (rows, cols)), shape=(k, graph.n))

    @staticmethod
    def _length_rows(graph):
        """v_i - v_j for the edges off the boundary, E_g (eq. 4)."""
        n = graph.n
        loop_keys = np.concatenate([np.minimum(loop, np.roll(loop, -1)) * n + np.maximum(loop, np.roll(loop, -1))
                                    for loop in graph.boundary_loops])
        keys = graph.edges[:, 0] * n + graph.edges[:, 1]
        inner = graph.edges[~np.isin(keys, loop_keys)]
        k = len(inner)
        rows = np.concatenate([np.arange(k), np.arange(k)])
        cols = np.concatenate([inner[:, 0], inner[:, 1]])
        vals = np.concatenate([np.ones(k), -np.ones(k)])
        return coo_matrix((vals, (rows, cols)), shape=(k, n)), inner

    def local_step(self, rows):
        """``A V - b(V)`` from ``A V``: the local step and the residual in one.

        Parameters
        ----------
        rows : (2, r) float ndarray
            ``A @ V``, coordinate-major.

        Returns
        -------
        residual : (2, r) float64 ndarray
        fit : LocalFit
            The fitted rotations and edge lengths, which the Newton matrix
            (:mod:`solver.hessian`) is built from at the same pose.
        """
        fit = self.fit(rows)
        residual = np.empty_like(rows)
        curve, lengths = self.curve_rows, self.length_rows
        mvc = slice(curve.stop, lengths.start)
        residual[:, mvc] = rows[:, mvc]  # mean value rows have target zero
        # Each boundary vertex's three rest rows, turned by its fitted rotation (section 4.2).
        cos, sin = fit.cos, fit.sin
        rest_x, rest_y = self._curve_rest_x, self._curve_rest_y
        now = rows[:, curve].reshape(2, 3, -1)
        turned = residual[:, curve].reshape(2, 3, -1)  # a view: written through
        np.subtract(now[0], cos * rest_x - sin * rest_y, out=turned[0])
        np.subtract(now[1], sin * rest_x + cos * rest_y, out=turned[1])
        # Nearest vector of rest length for each inner edge (eq. 4's e(v_i, v_j)).
        edge = rows[:, lengths]
        length = fit.edge_length
        if length.min(initial=1.0) > 0.0:
            np.multiply(edge, 1.0 - self.rest_length / length, out=residual[:, lengths])
        else:  # a collapsed edge: any direction is optimal; keep its rest direction
            direction = self._rest_direction.copy()
            ok = length > 0.0
            direction[:, ok] = edge[:, ok] / length[ok]
            residual[:, lengths] = edge - self.rest_length * direction
        return residual, fit

    def residual(self, rows):
        """``A V - b(V)`` from ``A V`` ((2, r), coordinate-major); see :meth:`local_step`."""
        return self.local_step(rows)[0]

    def targets(self, rows_now):
        """The local step: ``b(V)`` from ``A V``.

        Parameters
        ----------
        rows_now : (r, 2) float ndarray
            ``A @ V`` at the current positions.

        Returns
        -------
        (r, 2) float64 ndarray
        """
        rows = np.ascontiguousarray(np.asarray(rows_now, dtype=np.float64).T)
        return (rows - self.residual(rows)).T

    def fit(self, rows):
        """The local fit alone: each boundary vertex's rotation fitted to its three curve rows
        (2D Procrustes) and the inner edges' current lengths, from ``A V`` ((2, r)).

        Returns
        -------
        LocalFit
        """
        rest_x, rest_y = self._curve_rest_x, self._curve_rest_y
        now_x, now_y = rows[:, self.curve_rows].reshape(2, 3, -1)
        dot = rest_x * now_x
        dot += rest_y * now_y
        cross = rest_x * now_y
        cross -= rest_y * now_x
        cos = dot[0] + dot[1] + dot[2]
        sin = cross[0] + cross[1] + cross[2]
        norm = np.sqrt(cos * cos + sin * sin)  # np.hypot is 3x slower here
        if norm.min(initial=1.0) > 0.0:
            cos, sin = cos / norm, sin / norm
        else:  # a vertex whose rows all vanish: any rotation fits; take none
            degenerate = norm == 0.0
            safe = np.where(degenerate, 1.0, norm)
            cos, sin = np.where(degenerate, 1.0, cos / safe), np.where(degenerate, 0.0, sin / safe)
        edge = rows[:, self.length_rows]
        edge_x, edge_y = edge
        return LocalFit(cos, sin, norm, np.sqrt(edge_x * edge_x + edge_y * edge_y))

    def evaluate(self, positions):
        """Energy and residual at ``positions``.

        Parameters
        ----------
        positions : (n, 2) float ndarray

        Returns
        -------
        energy : float
        residual : (r, 2) float64 ndarray
            ``A V - b(V)``.
        """
        residual = self.residual(np.ascontiguousarray((self.matrix @ positions).T))
        return float(np.vdot(residual, residual)), residual.T


class UncoveredPoints(ValueError):
    """Free points that no term with a positive weight has rows on: nothing decides where they go.

    Attributes
    ----------
    count : int
        How many.
    terms : list of str
        The weights (keys of ``Energy.weights``) that, made positive, would cover them all; when
        no single one would, each that covers some.
    """

    def __init__(self, count, terms):
        self.count, self.terms = count, terms
        super().__init__(self.explain())

    def explain(self, weight_name=repr):
        """The refusal, each weight named by ``weight_name`` (a term's key to its name as the
        caller shows it; quoted keys by default)."""
        count = self.count
        return (f"with these weights {count} {by_count(count, 'point is', 'points are')} in no energy term and "
                f"nothing decides where {by_count(count, 'it goes', 'they go')}; give "
                f"{' or '.join(map(weight_name, self.terms))} a positive weight")


def uncovered_points(energy, points):
    """:class:`UncoveredPoints` for ``points`` (k,) int, which no weighted term covers."""
    covers = {term: np.isin(points, touched) for term, touched in energy.term_points.items()}
    whole = [term for term, covered in covers.items() if covered.all()]
    some = [term for term, covered in covers.items() if covered.any()]
    # No term has rows on them (points on no triangle): any weight left at zero is all to try.
    return UncoveredPoints(len(points), whole or some or [t for t, w in energy.weights.items() if w == 0.0])


def similarity_rows(points, triangles):
    """Rows of the linear as-similar-as-possible energy, on stacked coordinates ``[x; y]``.

    For each triangle corner ``a`` with the next corners ``b, c``, the rest shape gives the
    complex ratio ``w = (c - a) / (b - a)``; a pose where every triangle is a rotated, scaled
    copy of its rest self satisfies ``(c - a) - w (b - a) = 0``. The rows are linear, and a
    least-squares pose under handle constraints is smooth and rotates free limbs with what they
    hang from: a start for the nonlinear solve that depends on the handle targets alone. (Not
    the paper's: the first, similarity step of Igarashi, Moscovich and Hughes 2005,
    "As-rigid-as-possible shape manipulation".)

    Parameters
    ----------
    points : (n, 2) float ndarray
        Rest positions.
    triangles : (t, 3) int ndarray

    Returns
    -------
    (6 t, 2 n) scipy.sparse.csr_matrix
        Acting on ``np.concatenate([x, y])``.
    """
    n = len(points)
    z = points[:, 0] + 1j * points[:, 1]
    rows, cols, vals = [], [], []
    count = 0
    for shift in range(3):
        a, b, c = (np.roll(triangles, -shift, axis=1)[:, k] for k in range(3))
        base = z[b] - z[a]
        ok = np.abs(base) > 0
        w = np.where(ok, (z[c] - z[a]) / np.where(ok, base, 1.0), 0.0)
        p, q = w.real, w.imag
        t = len(a)
        rx = count + np.arange(t)      # real part rows
        ry = rx + t                     # imaginary part rows
        # real: (x_c - x_a) - p (x_b - x_a) + q (y_b - y_a)
        rows += [rx] * 6
        cols += [c, a, b, a, n + b, n + a]
        vals += [np.ones(t), -np.ones(t), -p, p, q, -q]
        # imaginary: (y_c - y_a) - p (y_b - y_a) - q (x_b - x_a)
        rows += [ry] * 6
        cols += [n + c, n + a, n + b, n + a, b, a]
        vals += [np.ones(t), -np.ones(t), -p, p, -q, q]
        count += 2 * t
    return coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(count, 2 * n)).tocsr()
