"""The Newton matrix: the energy's true Hessian wherever its projection is inactive."""

import numpy as np
import pytest

import solver
from benchmarks import random_drags
from sample_shapes import glyph_rings


def _stretched(prevent_flips, spacing=None, normalise_density=False):
    """A 'B' scaled up by 1.5 plus a little noise: every edge is stretched and every curve
    group's fit is below its rest norm, so no coefficient of the Newton matrix is clamped."""
    graph = solver.build_graph(glyph_rings("B"), spacing=spacing)
    handles = np.flatnonzero(graph.points[:, 1] < graph.points[:, 1].min() + 0.5)
    deformer = solver.Deformer(graph, handles, prevent_flips=prevent_flips, newton=True,
                               normalise_density=normalise_density)
    rng = np.random.default_rng(7)
    pose = 1.5 * graph.points + 1e-3 * graph.size * rng.normal(size=graph.points.shape)
    fixed_rows = (deformer._fixed_columns @ pose[deformer.unknowns.fixed]).T.ravel()
    deformer._fixed_rows = fixed_rows  # what solve() holds for evaluate()
    return graph, deformer, pose, fixed_rows, rng


def _squeeze(graph, deformer, pose, count):
    """Squeeze the first ``count`` inner triangles of ``pose`` past the fold threshold (their
    third corner pulled onto their first edge) and hold the fixed points for ``evaluate``.
    Returns the free coordinates, the rows ``A V`` and the penalty's terms there."""
    inner = graph.triangles[np.isin(graph.triangles, deformer.free).all(axis=1)][:count]
    for a, b, c in inner:
        pose[c] = pose[a] + 0.02 * (pose[c] - pose[a]) + 0.5 * (pose[b] - pose[a])
    deformer._folds.hold(pose[deformer.unknowns.fixed])
    deformer._fixed_rows = (deformer._fixed_columns @ pose[deformer.unknowns.fixed]).T.ravel()
    v = pose[deformer.free].T.ravel()
    return v, deformer.evaluate(v)[2][0], deformer._folds.terms(v)


def _assert_matches_finite_differences(deformer, v, upper, rng):
    """The symmetric matrix with upper triangle ``upper`` times random directions equals central
    differences of the deformer's (half) gradient: it is the Hessian, halved as the gradient is."""
    upper = upper.toarray()
    newton = upper + np.triu(upper, 1).T
    step = 1e-6 * deformer.graph.size
    for _ in range(4):
        direction = rng.normal(size=v.shape)
        ahead = deformer.evaluate(v + step * direction)[1]
        behind = deformer.evaluate(v - step * direction)[1]
        exact = newton @ direction
        assert np.abs((ahead - behind) / (2 * step) - exact).max() <= 1e-6 * np.abs(exact).max()


@pytest.mark.parametrize("normalised", [False, True])
def test_newton_matrix_matches_finite_differences_of_the_gradient(normalised):
    """Also with the density normalisation on a graph finer than the default, where a curve
    group's Laplacian row and edge rows have different weights."""
    spacing = None
    if normalised:
        rings = glyph_rings("B")
        spacing = 0.6 * solver.graph.default_spacing(solver.shapes.shape_geometry(rings))
    graph, deformer, pose, fixed_rows, rng = _stretched(False, spacing, normalised)
    if normalised:
        kinds = deformer.energy.curve_kind_scale
        assert kinds[0] > kinds[1] > 1.0
    v = pose[deformer.free].T.ravel()
    rows = deformer.evaluate(v)[2][0]
    _assert_matches_finite_differences(deformer, v, deformer._preconditioner.matrix(rows), rng)


def test_exact_newton_matrix_with_squeezed_triangles_matches_finite_differences():
    """The exact matrix includes the fold penalty's whole Hessian: its Gauss-Newton part and the
    area's own curvature weighted by how far each triangle is squeezed."""
    graph, deformer, pose, _, rng = _stretched(prevent_flips=True)
    v, rows, terms = _squeeze(graph, deformer, pose, 3)
    assert np.count_nonzero(terms.bend) >= 2
    exact = deformer._preconditioner.matrix(rows, terms, filtering="exact")
    _assert_matches_finite_differences(deformer, v, exact, rng)


def test_fold_terms_add_the_penalty_gauss_newton_matrix():
    """With a triangle squeezed below the fold threshold, the projected Newton matrix gains
    exactly ``E''(a) / 2 grad(a) grad(a)^T`` for it (the penalty's Gauss-Newton part, halved),
    with ``E(a) = w a0 (t - a / a0)^3 / (3 t^2)`` as solver.folds defines it."""
    options = solver.Options()
    weight, threshold = options.fold_weight, options.fold_threshold

    graph, deformer, pose, _, _ = _stretched(prevent_flips=True)
    v, rows, terms = _squeeze(graph, deformer, pose, 1)
    folds = deformer._folds
    assert terms is not None and np.count_nonzero(terms.coefficient) >= 1
    added = deformer._preconditioner.matrix(rows, terms).toarray() - deformer._preconditioner.matrix(rows, None).toarray()
    expected = np.zeros_like(added)
    step = 1e-7 * graph.size
    rest_area = 0.5 * solver.triangulate.triangle_cross(graph.points, graph.triangles)
    ratio = folds._areas(v)[1] / rest_area
    for t in np.flatnonzero(terms.coefficient):
        gradient = np.zeros_like(v)
        for k in range(len(v)):  # the triangle's area gradient, by central differences
            if not np.isin(k % len(deformer.free), np.searchsorted(deformer.free, graph.triangles[t])):
                continue
            e = np.zeros_like(v)
            e[k] = step
            gradient[k] = (folds._areas(v + e)[1][t] - folds._areas(v - e)[1][t]) / (2 * step)
        half_curvature = weight * (threshold - ratio[t]) / (threshold ** 2 * rest_area[t])
        expected += half_curvature * np.outer(gradient, gradient)
    assert np.abs(added - np.triu(expected)).max() <= 1e-6 * np.abs(expected).max()


def test_two_grid_cycle_gives_descent_directions_and_its_coarse_matrix_is_galerkin():
    """The two-grid preconditioner is not symmetric, but ``g^T M g > 0`` for every ``g`` (see
    solver.two_grid), and its coarse matrix is ``P^T H P`` of the whole Newton matrix."""
    graph = solver.build_graph(glyph_rings("B"))
    handles = np.flatnonzero(graph.points[:, 1] < graph.points[:, 1].min() + 0.5)
    # The two-grid serves graphs above Options.newton_max_points: lowered here to reach it.
    deformer = solver.Deformer(graph, handles, options=solver.Options(newton_max_points=0))
    two_grid = deformer._preconditioner._two_grid
    pose = graph.points @ np.array([[0.8, -0.6], [0.6, 0.8]]).T * 1.2  # turned and stretched
    rows = np.ascontiguousarray((deformer.energy.matrix @ pose).T)
    two_grid.factorize(rows)
    whole = solver.hessian.Hessian(deformer.energy, deformer.free).matrix(rows).toarray()
    whole = whole + whole.T - np.diag(whole.diagonal())
    up = two_grid._up.toarray()
    coarse = two_grid._coarse_upper.toarray()
    coarse = coarse + coarse.T - np.diag(coarse.diagonal())
    galerkin = up.T @ whole @ up
    assert np.abs(coarse - galerkin).max() <= 1e-8 * np.abs(galerkin).max()
    rng = np.random.default_rng(3)
    gradients = rng.normal(size=(50, whole.shape[0]))
    gradients[:10] = np.linalg.eigh(whole)[1][:, :10].T  # the softest directions too
    for g in gradients:
        assert float(g @ two_grid.solve(g)) > 0.0
    # The symmetric cycle, CG's preconditioner, is a symmetric positive definite map.
    symmetric = np.column_stack([two_grid.symmetric_solve(e) for e in np.eye(whole.shape[0])])
    assert np.abs(symmetric - symmetric.T).max() <= 1e-9 * np.abs(symmetric).max()
    assert np.linalg.eigvalsh(0.5 * (symmetric + symmetric.T)).min() > 0.0


def test_two_grid_takes_fold_terms_into_its_smoother_without_refactorising():
    """Squeezed triangles' penalty terms ``G G^T`` go into the smoother as ``(K + G G^T)^-1``
    (Woodbury, on the kept factor of K) and into the coarse matrix; directions stay descent."""
    graph = solver.build_graph(glyph_rings("B"))
    handles = np.flatnonzero(graph.points[:, 1] < graph.points[:, 1].min() + 0.5)
    # L-BFGS's two-grid, which large graphs keep with the area constraint (newton_max_points
    # lowered to reach it).
    deformer = solver.Deformer(graph, handles, prevent_flips=True, preserve_area=True,
                               options=solver.Options(newton_max_points=0))
    two_grid = deformer._preconditioner
    factor = two_grid._smoother._factor
    rows = np.ascontiguousarray((deformer.energy.matrix @ graph.points).T)
    inner = np.flatnonzero(np.isin(graph.triangles, deformer.free).all(axis=1))[:5]
    coefficient = np.zeros(len(graph.triangles))
    coefficient[inner] = -3.0
    u = np.random.default_rng(5).normal(size=(len(graph.triangles), 6))
    two_grid.factorize(rows, solver.folds.FoldTerms(coefficient, u, np.zeros_like(coefficient)))
    assert two_grid._smoother._factor is factor
    f = len(deformer.free)
    slot = np.searchsorted(deformer.free, graph.triangles[inner])
    g = np.zeros((2 * f, len(inner)))
    for j in range(len(inner)):
        g[np.concatenate([slot[j], slot[j] + f]), j] = np.sqrt(3.0) * u[inner[j]]
    columns = deformer.energy.matrix.tocsc()[:, deformer.free]
    k = (columns.T @ columns).toarray()
    smoother = np.kron(np.eye(2), k) + g @ g.T
    r = np.linspace(-1.0, 1.0, 2 * f)
    assert np.allclose(two_grid._smooth(r), np.linalg.solve(smoother, r), rtol=1e-8, atol=1e-12)
    for v in np.random.default_rng(6).normal(size=(20, 2 * f)):
        assert float(v @ two_grid.solve(v)) > 0.0


def test_krylov_newton_solves_the_exact_system_or_returns_a_descent_direction():
    """CG over the two-grid: at a pose whose exact Hessian is positive definite, with a tiny
    forcing term, the step is the exact Newton step; far from a minimum (negative curvature) it
    is still a descent direction, flagged not exact; and the fine factor is never refactorised."""
    graph = solver.build_graph(glyph_rings("B"))
    handles = np.flatnonzero(graph.points[:, 1] < graph.points[:, 1].min() + 0.5)
    targets = graph.points[handles] @ np.array([[0.0, -1.0], [1.0, 0.0]]).T  # a quarter turn
    options = solver.Options(newton_max_points=0)  # graphs above it take Krylov-Newton steps
    deformer = solver.Deformer(graph, handles, prevent_flips=True, options=options)
    krylov = deformer._preconditioner
    assert isinstance(krylov, solver.krylov.KrylovNewton)
    factor = krylov._two_grid._smoother._factor
    minimum = deformer.solve(targets, tolerance=1e-9, max_iterations=200)
    assert minimum.converged

    def free_coordinates(positions):
        """Hold the fixed points of ``positions`` for evaluate(), as solve() does; the free ones."""
        fixed = positions[deformer.unknowns.fixed]
        deformer._folds.hold(fixed)
        deformer._fixed_rows = (deformer._fixed_columns @ fixed).T.ravel()
        return positions[deformer.free].T.ravel()

    v = free_coordinates(minimum.positions) + 1e-4 * graph.size * np.random.default_rng(2).normal(
        size=2 * len(deformer.free))
    _, gradient, pose = deformer.evaluate(v)
    deformer.refresh(v, pose)
    exact = krylov._matrix.toarray()
    assert np.linalg.eigvalsh(exact).min() > 0.0
    step = krylov.solve(gradient, forcing=1e-12)
    assert krylov.exact
    assert np.allclose(step, np.linalg.solve(exact, gradient), rtol=1e-6, atol=1e-10 * np.abs(step).max())

    start = free_coordinates(deformer.solve(targets, max_iterations=0).positions)
    _, gradient, pose = deformer.evaluate(start)
    deformer.refresh(start, pose)
    for forcing in (0.5, 1e-3):
        assert float(gradient @ krylov.solve(gradient, forcing)) > 0.0
    assert krylov._two_grid._smoother._factor is factor


def test_newton_steps_with_the_least_projection_that_is_positive_definite():
    """Along a random drag's solve, each Newton step solves with the exact Hessian where it is
    positive definite, else with the mean of it and its projection where that is, else with the
    projection: the three are seen, and the factor solves the one expected."""
    case = random_drags.cases(6174, "paper", shapes=["glyph &"], drags=3)[2]
    deformer = solver.Deformer(case.graph, case.handles, prevent_flips=True)
    newton = deformer._preconditioner
    seen = set()
    for iterations in range(7):
        positions = deformer.solve(case.targets, max_iterations=iterations).positions
        fixed = positions[deformer.unknowns.fixed]
        deformer._folds.hold(fixed)
        deformer._fixed_rows = (deformer._fixed_columns @ fixed).T.ravel()
        v = positions[deformer.free].T.ravel()
        _, gradient, (rows, _) = deformer.evaluate(v)
        terms = deformer._folds.terms(v)
        exact, projected = (newton.matrix(rows, terms, filtering=kind).toarray() for kind in ("exact", "clamp"))
        exact, projected = (m + np.triu(m, 1).T for m in (exact, projected))
        candidates = {"exact": exact, "halfway": 0.5 * (exact + projected), "projected": projected}
        kind = next(name for name, m in candidates.items() if np.linalg.eigvalsh(m).min() > 0.0)
        seen.add(kind)
        deformer.refresh(v)
        assert newton.exact == (kind == "exact")
        expected = np.linalg.solve(candidates[kind], gradient)
        assert np.allclose(newton.solve(gradient), expected, rtol=1e-6, atol=1e-9 * np.abs(expected).max())
    assert seen == {"exact", "halfway", "projected"}
