"""The deformer: exact handles, exact area, falling energy, real convergence, kept detail."""

import numpy as np
import pytest

import solver
from solver.folds import FoldPenalty
from solver.unknowns import Unknowns
from solver.triangulate import triangle_cross
from sample_shapes import disk, figure_rings, glyph_rings, hooves_and_head, region


def flipped(graph, positions):
    a, b, c = (positions[graph.triangles[:, k]] for k in range(3))
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    return int((cross <= 0).sum())


def rotation(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def test_rigid_motion_of_all_handles_is_a_rigid_motion(horse_graph, horse_drag):
    handles = horse_drag[0]
    points = horse_graph.points
    moved = points @ rotation(0.7).T + [35.0, -12.0]
    pose = solver.Deformer(horse_graph, handles).solve(moved[handles])
    assert np.abs(pose.positions - moved).max() <= 1e-5 * horse_graph.size


def test_handles_are_exact_and_energy_never_rises(horse_graph, horse_drag):
    handles, targets, _ = horse_drag
    pose = solver.Deformer(horse_graph, handles).solve(targets)
    assert np.array_equal(pose.positions[handles], targets)
    assert len(pose.energies) == pose.iterations
    assert np.all(np.diff(pose.energies) <= 0.0)
    assert np.all(np.isfinite(pose.positions))


def test_a_free_limb_swinging_about_a_handle_converges_within_the_render_budget(horse_graph):
    """Two handle regions pulling against each other, the head free to swing about the dragged
    one: a flat valley, which the solve crawls along once its first refreshes are spent. After
    30 iterations it was 7.8e-2 of the size off its minimum; later refreshes bring it within
    1e-3."""
    points, size = horse_graph.points, horse_graph.size
    pinned = region(points, (276.5, 225.1), 0.05 * size)
    dragged = np.setdiff1d(region(points, (311.4, 231.1), 0.05 * size), pinned)
    c, s = np.cos(-0.111), np.sin(-0.111)
    turned = (points[dragged] - (311.4, 231.1)) @ np.array([[c, -s], [s, c]]).T + (311.4 - 12.0, 231.1 + 73.1)
    handles = np.concatenate([pinned, dragged])
    targets = np.concatenate([points[pinned], turned])
    deformer = solver.Deformer(horse_graph, handles)
    minimum = deformer.solve(targets, max_iterations=3000, tolerance=1e-9)
    pose = deformer.solve(targets, max_iterations=30)
    assert np.abs(pose.positions - minimum.positions).max() <= 1e-3 * size


def test_moving_handles_reuses_the_symbolic_analysis(horse_graph, horse_drag):
    """Newton refactorises its matrix's values at every iterate, never its pattern: one symbolic
    analysis per handle set, kept from one handle move to the next."""
    handles, targets, _ = horse_drag
    deformer = solver.Deformer(horse_graph, handles)
    assert isinstance(deformer._preconditioner, solver.hessian.NewtonMatrix)
    rest = horse_graph.points[handles]
    deformer.solve(rest + (targets - rest) * 0.25)
    factor = deformer._preconditioner._factor
    for t in (0.5, 1.0, 0.75):
        moved = rest + (targets - rest) * t
        pose = deformer.solve(moved)
        assert np.array_equal(pose.positions[handles], moved)
        assert deformer._preconditioner._factor is factor


def test_a_graph_too_small_for_a_coarse_copy_starts_as_similar_as_possible():
    """A graph with fewer points than two coarse copies would have starts from the
    as-similar-as-possible pose instead of a coarse copy's (and still converges)."""
    graph = solver.build_graph([disk(count=24)], spacing=0.3)
    assert graph.n < 2 * solver.Options().coarse_interior
    handles = np.flatnonzero(np.abs(graph.points[:, 0]) > 0.8)
    deformer = solver.Deformer(graph, handles)
    assert [type(start) for start in deformer._starts] == [solver.start.SimilarityStart]
    targets = graph.points[handles] * [1.3, 1.0]
    pose = deformer.solve(targets)
    assert pose.converged and np.array_equal(pose.positions[handles], targets)


def test_tolerance_zero_runs_exactly_max_iterations(horse_graph, horse_drag):
    handles, targets, _ = horse_drag
    pose = solver.Deformer(horse_graph, handles).solve(targets, max_iterations=40, tolerance=0.0)
    assert pose.iterations == 40 and len(pose.energies) == 40


@pytest.mark.parametrize("rings_name", ["horse", "glyph"])
def test_global_area_is_exact(rings_name, horse_graph, horse_drag):
    if rings_name == "horse":
        graph, (handles, targets, _) = horse_graph, horse_drag
    else:  # a letter with two holes: its area is the outline minus the holes
        graph = solver.build_graph(glyph_rings("B"))
        left = np.flatnonzero(graph.points[:, 0] < graph.points[:, 0].min() + 0.6)
        right = np.flatnonzero(graph.points[:, 0] > graph.points[:, 0].max() - 0.6)
        handles = np.concatenate([left, right])
        targets = graph.points[handles].copy()
        targets[len(left):, 0] += 4.0  # stretch the letter
    pose = solver.Deformer(graph, handles, preserve_area=True).solve(targets)
    assert abs(graph.area(pose.positions) / graph.area() - 1.0) <= 1e-9
    assert np.array_equal(pose.positions[handles], targets)
    assert np.all(np.diff(pose.energies) <= 0.0)
    free = solver.Deformer(graph, handles).solve(targets)
    assert abs(graph.area(free.positions) / graph.area() - 1.0) > 1e-6  # the constraint did something


def test_global_area_is_exact_after_a_drag_a_hundred_times_the_size():
    """A thin bar with part of it dragged 100 times its size away: the start pose has 100 times
    the area, beyond reach along the solver's first direction. The solve used to return that
    start untouched after 0 iterations; now the area is met."""
    graph = solver.build_graph([np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0 / 30.0], [0.0, 1.0 / 30.0]])])
    pinned = region(graph.points, (0.5, 0.017), 0.05)
    dragged = np.setdiff1d(region(graph.points, (0.6, 0.017), 0.065), pinned)
    handles = np.concatenate([pinned, dragged])
    targets = np.concatenate([graph.points[pinned], graph.points[dragged] + [94.5, 40.75]])
    pose = solver.Deformer(graph, handles, preserve_area=True).solve(targets)
    assert pose.iterations > 0 and np.all(np.isfinite(pose.positions))
    assert abs(graph.area(pose.positions) / graph.area() - 1.0) <= 1e-9
    assert np.array_equal(pose.positions[handles], targets)


# A five-sided ring found by fuzzing: its slanted edges, subdivided a million units from the
# origin, gave flat boundary triangles.
SLANTED = np.array([[0.3540135422954336, -1.0895416509592906], [-0.7277013721177354, -0.5287059945985675],
                    [-0.6504876326071098, 0.4726069290190935], [0.3020956616383046, 0.929754844517447],
                    [1.015685724443756, 0.0]])


def test_global_area_is_exact_with_an_island_dragged_a_hundred_times_the_size_away():
    """One island carried far off by its handles, the other at rest: the pose spans 100 times
    the size, and rounding in the start's solve leaves its area 1e-8 off, under the rounding
    bound of so large a sum; the projection must still correct it, not excuse it."""
    graph = solver.build_graph([disk(1.0, 48), disk(0.7, 40, centre=(3.0, 0.0))])
    carried = region(graph.points, (0.0, 0.0), 0.3)
    targets = graph.points[carried] + [300.0, 120.0]
    pose = solver.Deformer(graph, carried, preserve_area=True).solve(targets)
    assert abs(graph.area(pose.positions) / graph.area() - 1.0) <= 1e-9


@pytest.mark.parametrize("options", [{}, {"preserve_area": True}, {"prevent_flips": True}])
def test_a_shape_far_from_the_origin_builds_binds_and_deforms_as_at_the_origin(options):
    """A star with a hole, a millionth of its offset in size. Triangulated in absolute
    coordinates, the graph build split segments round after round for minutes; then points
    subdivided along its slanted edges, off the edge by the offset's rounding, made flat boundary
    triangles: binding put weights of 1e288 on points outside, and the fold penalty overflowed."""
    rings = [SLANTED, disk(0.2, 24)]
    offset = np.array([1e6, -7e5])
    near = solver.build_graph(rings)
    far = solver.build_graph([ring + offset for ring in rings])
    assert abs(far.n - near.n) <= 0.02 * near.n
    assert far.area() == pytest.approx(near.area(), rel=1e-9)
    corners = far.points[far.triangles] - offset
    cross = triangle_cross(corners.reshape(-1, 2), np.arange(3 * len(corners)).reshape(-1, 3))
    assert cross.min() > 1e-6 * far.size ** 2 and 0.5 * cross.sum() == pytest.approx(far.area(), rel=1e-6)
    outside = offset + [[1.2, 0.0], [0.0, -1.2], [-0.9, 0.9], [0.8, 0.8]]
    binding = solver.bind(far, outside)
    assert np.abs(binding.weights.data).max() < 100.0
    assert np.abs(binding.apply(far.points) - outside).max() <= 1e-8 * far.size
    top = np.flatnonzero(far.points[:, 1] > offset[1] + 0.7)
    bottom = np.flatnonzero(far.points[:, 1] < offset[1] - 0.8)
    handles = np.concatenate([bottom, top])
    targets = far.points[handles] + np.where(np.isin(handles, top)[:, None], [0.4, 0.2], 0.0)
    pose = solver.Deformer(far, handles, **options).solve(targets)
    assert np.all(np.isfinite(pose.positions)) and np.array_equal(pose.positions[handles], targets)
    if options.get("preserve_area"):
        assert abs(far.area(pose.positions) / far.area() - 1.0) <= 1e-9
    # One handle point leaves turns free: they settle towards rest, which the offset's rounding
    # in the start's solve used to swamp (the shape turned by about its size).
    still = solver.Deformer(far, [5], **options).solve(far.points[[5]])
    assert np.abs(still.positions - far.points).max() <= 1e-4 * far.size


def test_area_of_a_thin_stretched_ring_is_exact():
    """The plain shoelace sum cancels digits on a long thin slanted ring (2e-9 of its area here,
    centred); the trapezoid form keeps them (checked against exact rational arithmetic)."""
    from fractions import Fraction

    from solver.shapes import signed_area

    rng = np.random.default_rng(5)
    x = np.concatenate([np.linspace(0.0, 100.0, 2000), np.linspace(100.0, 0.0, 2000)])
    y = np.concatenate([np.zeros(2000), np.full(2000, 0.001)]) + rng.normal(0.0, 2e-5, 4000)
    c, s = np.cos(0.7), np.sin(0.7)
    ring = np.stack([x, y], axis=1) @ np.array([[c, -s], [s, c]]).T + [123.0, 45.0]
    fx, fy = [Fraction(float(v)) for v in ring[:, 0]], [Fraction(float(v)) for v in ring[:, 1]]
    exact = sum(fx[i] * fy[(i + 1) % 4000] - fx[(i + 1) % 4000] * fy[i] for i in range(4000)) / 2
    assert abs(signed_area(ring) - float(exact)) <= 1e-12 * abs(float(exact))


def test_preserve_area_says_why_when_no_boundary_point_can_move():
    left, right = disk(1.0, 32), disk(1.0, 32, centre=(3.0, 0.0))
    graph = solver.build_graph([left, right])
    on_left = np.flatnonzero(graph.points[:, 0] < 1.5)
    handles = np.intersect1d(on_left, graph.boundary)  # the left island's whole outline; none on the right
    with pytest.raises(ValueError, match="island without handles"):
        solver.Deformer(graph, handles, preserve_area=True)


def test_pose_depends_on_targets_only(horse_graph, horse_drag):
    """A render farm renders frames out of order: frame 30 must not depend on frames 1-29."""
    handles, targets, head = horse_drag
    deformer = solver.Deformer(horse_graph, handles)
    rest = horse_graph.points[handles]
    frames = [rest + (targets - rest) * t for t in np.linspace(0, 1, 31)[1:]]
    jumped = deformer.solve(frames[-1]).positions
    for frame in frames:  # played in order, as in the viewport
        played = deformer.solve(frame).positions
    assert np.abs(played - jumped).max() <= 1e-3 * horse_graph.size


def test_warm_start_on_a_moderate_drag_reaches_the_same_pose(horse_graph, horse_drag):
    handles, targets, head = horse_drag
    deformer = solver.Deformer(horse_graph, handles)
    rest = horse_graph.points[handles]
    goal = rest.copy()
    goal[-head:] += [-40.0, 30.0]
    jumped = deformer.solve(goal).positions
    pose = None
    for t in np.linspace(0, 1, 31)[1:]:
        pose = deformer.solve(rest + (goal - rest) * t, initial=None if pose is None else pose.positions)
    assert np.abs(pose.positions - jumped).max() <= 1e-3 * horse_graph.size


def bumpy_bar(length=10.0, bumps=(3.0, 5.0, 7.0), height=0.3, width=0.8):
    """A 10 x 1 bar with round bumps on its top edge; returns the ring and bump apex/base x."""
    top = [np.array([length, 1.0])]
    for x in sorted(bumps, reverse=True):
        t = np.linspace(1.0, 0.0, 9)
        top.append(np.stack([x - width / 2 + width * t, 1.0 + height * np.sin(np.pi * t)], axis=1))
    top.append(np.array([[0.0, 1.0]]))
    bottom = np.stack([np.linspace(0, length, 41)[:-1], np.zeros(40)], axis=1)
    ring = np.concatenate([bottom, np.vstack(top)])
    return ring


def bump_heights(positions, graph, bumps=(3.0, 5.0, 7.0), width=0.8, rest=None):
    rest = graph.points if rest is None else rest
    heights = []
    for x in bumps:
        apex = np.argmin(np.linalg.norm(rest - [x, 1.3], axis=1))
        left = np.argmin(np.linalg.norm(rest - [x - width / 2, 1.0], axis=1))
        right = np.argmin(np.linalg.norm(rest - [x + width / 2, 1.0], axis=1))
        base = positions[right] - positions[left]
        offset = positions[apex] - positions[left]
        heights.append(abs(base[0] * offset[1] - base[1] * offset[0]) / np.linalg.norm(base))
    return np.array(heights)


def test_bumps_keep_their_size_on_a_bar_bent_90_degrees():
    graph = solver.build_graph([bumpy_bar()], spacing=0.2)
    points = graph.points
    left = np.flatnonzero(points[:, 0] <= 0.5)
    right = np.flatnonzero(points[:, 0] >= 9.5)
    radius = 10.0 / (np.pi / 2)  # the bottom edge becomes a quarter circle
    angle = points[right, 0] / radius
    bent = np.stack([(radius + points[right, 1]) * np.sin(angle),
                     (radius + points[right, 1]) * np.cos(angle) - radius], axis=1)
    handles = np.concatenate([left, right])
    targets = np.concatenate([points[left], bent])
    pose = solver.Deformer(graph, handles).solve(targets)
    rest_heights = bump_heights(points, graph)
    heights = bump_heights(pose.positions, graph)
    assert np.allclose(rest_heights, 0.3, rtol=0.05)
    assert np.all(np.abs(heights / rest_heights - 1.0) <= 0.15), heights / rest_heights
    assert flipped(graph, pose.positions) == 0


def test_extreme_drags_stay_finite(horse_graph, horse_drag):
    handles, targets, head = horse_drag
    far = targets.copy()
    far[-head:] += 100.0 * horse_graph.size
    for area in (False, True):
        pose = solver.Deformer(horse_graph, handles, preserve_area=area).solve(far)
        assert np.all(np.isfinite(pose.positions))
        assert np.array_equal(pose.positions[handles], far)


def test_islands_without_handles_stay_put():
    rings = glyph_rings("i")  # dot and stem: two islands
    graph = solver.build_graph(rings)
    labels = graph.components()
    stem = labels == labels[np.argmin(graph.points[:, 1])]
    handles = np.flatnonzero(stem & (graph.points[:, 1] < 0.5))
    pose = solver.Deformer(graph, handles).solve(graph.points[handles] + [1.0, 0.0])
    assert np.array_equal(pose.positions[~stem], graph.points[~stem])
    assert np.all(pose.positions[stem, 0] > graph.points[stem, 0])


def test_weights_change_the_result_and_bad_weights_are_refused(horse_graph, horse_drag):
    handles, targets, _ = horse_drag
    a = solver.Deformer(horse_graph, handles).solve(targets).positions
    b = solver.Deformer(horse_graph, handles, weights={"edge": 10.0}).solve(targets).positions
    assert np.abs(a - b).max() > 1e-3 * horse_graph.size
    with pytest.raises(ValueError, match="unknown energy term"):
        solver.Deformer(horse_graph, handles, weights={"bending": 1.0})
    with pytest.raises(ValueError, match="weight"):
        solver.Deformer(horse_graph, handles, weights={"mvc": -1.0})


@pytest.mark.parametrize("targets, message", [
    (np.full((3, 2), np.nan), "non-finite"),
    (np.full((3, 2), np.inf), "non-finite"),
    (np.zeros((2, 2)), "shape"),
])
def test_bad_targets_are_refused(targets, message):
    graph = solver.build_graph([disk()])
    deformer = solver.Deformer(graph, [0, 1, 2])
    with pytest.raises(ValueError, match=message):
        deformer.solve(targets)


def test_bad_handles_are_refused():
    graph = solver.build_graph([disk()])
    with pytest.raises(ValueError, match="handle indices"):
        solver.Deformer(graph, [0, graph.n])
    with pytest.raises(ValueError, match="twice"):
        solver.Deformer(graph, [3, 3])
    with pytest.raises(ValueError, match="boundary point"):
        solver.Deformer(graph, graph.boundary, preserve_area=True)


def test_a_mesh_can_be_its_own_graph():
    """A user's quad grid: its boundary loop given clockwise, its own edges, no triangles."""
    x, y = np.meshgrid(np.arange(6.0), np.arange(4.0))
    points = np.stack([x.ravel(), y.ravel()], axis=1)
    index = np.arange(24).reshape(4, 6)
    edges = np.concatenate([np.stack([index[:, :-1].ravel(), index[:, 1:].ravel()], 1),
                            np.stack([index[:-1].ravel(), index[1:].ravel()], 1)])
    loop = np.concatenate([index[0], index[1:, -1], index[-1, ::-1][1:], index[::-1, 0][1:-1]])
    graph = solver.Graph(points, edges, [loop[::-1]])
    assert graph.area() == pytest.approx(15.0)
    assert len(graph.triangles) == 30
    handles = np.concatenate([index[:, 0], index[:, -1]])
    targets = points[handles] + np.where(points[handles, :1] > 0, [0.0, 2.0], [0.0, 0.0])
    pose = solver.Deformer(graph, handles).solve(targets)
    assert pose.converged and np.all(np.isfinite(pose.positions))
    assert flipped(graph, pose.positions) == 0


def test_a_point_in_no_triangle_starts_at_rest_and_stays_finite():
    """A user's mesh may carry a loose vertex hung on edges only: the similarity start has no
    row for it, so it starts from where it rests rather than the origin."""
    x, y = np.meshgrid(np.arange(4.0), np.arange(4.0))
    points = np.concatenate([np.stack([x.ravel(), y.ravel()], axis=1), [[1.5, 1.4]]])
    index = np.arange(16).reshape(4, 4)
    edges = np.concatenate([np.stack([index[:, :-1].ravel(), index[:, 1:].ravel()], 1),
                            np.stack([index[:-1].ravel(), index[1:].ravel()], 1), [[5, 16], [16, 10]]])
    loop = np.concatenate([index[0], index[1:, -1], index[-1, ::-1][1:], index[::-1, 0][1:-1]])
    grid = solver.Graph(points[:16], edges[:-2], [loop])
    graph = solver.Graph(points, edges, [loop], triangles=grid.triangles)
    handles = index[:, 0]
    deformer = solver.Deformer(graph, handles)
    start = deformer.solve(points[handles], max_iterations=0).positions
    assert np.abs(start[16] - points[16]).max() <= 1e-6
    pose = deformer.solve(points[handles] + [0.0, 1.0])
    assert np.all(np.isfinite(pose.positions)) and pose.converged


def test_large_graph_path_converges_from_a_coarse_start(horse_graph, horse_drag):
    """Above Options.newton_max_points the solve starts from a coarse copy's pose and takes
    Newton steps solved by CG over the two-grid preconditioner: the fine constant factor is
    never refactorised, only the small coarse one; exercised here on the horse by lowering the
    thresholds."""
    handles, targets, _ = horse_drag
    newton = solver.Deformer(horse_graph, handles, newton=True).solve(
        targets, tolerance=1e-8, max_iterations=200)
    options = solver.Options(coarse_start_points=10, newton_max_points=10)
    deformer = solver.Deformer(horse_graph, handles, options=options)
    assert isinstance(deformer._preconditioner, solver.krylov.KrylovNewton)
    fine_factor = deformer._preconditioner._two_grid._smoother._factor
    for t in (0.5, 1.0):
        rest = horse_graph.points[handles]
        pose = deformer.solve(rest + (targets - rest) * t)
        assert pose.converged
        assert deformer._preconditioner._two_grid._smoother._factor is fine_factor
        assert np.array_equal(pose.positions[handles], rest + (targets - rest) * t)
        assert np.all(np.diff(pose.energies) <= 0.0)
    assert np.abs(pose.positions - newton.positions).max() <= 1e-3 * horse_graph.size


def test_large_graphs_with_the_area_constraint_keep_l_bfgs(horse_graph, horse_drag):
    """The area constraint's projections need a factor: above Options.newton_max_points it is
    solved by L-BFGS over the two-grid, whose coarse matrix is refreshed a bounded number of
    times."""
    handles, targets, _ = horse_drag
    options = solver.Options(coarse_start_points=10, newton_max_points=10)
    deformer = solver.Deformer(horse_graph, handles, preserve_area=True, options=options)
    assert isinstance(deformer._preconditioner, solver.two_grid.TwoGrid)
    pose = deformer.solve(targets)
    assert np.array_equal(pose.positions[handles], targets)
    assert 1 <= pose.factorizations <= options.refreshes
    assert abs(horse_graph.area(pose.positions) / horse_graph.area() - 1.0) <= 1e-9


def test_very_large_graphs_keep_the_papers_factor(horse_graph, horse_drag):
    """Above Options.two_grid_max_points the default iterates the paper's matrix alone from the
    coarse copy's pose: no refactorisation at all (exercised by lowering both thresholds)."""
    handles, targets, _ = horse_drag
    options = solver.Options(coarse_start_points=10, newton_max_points=10, two_grid_max_points=20)
    pose = solver.Deformer(horse_graph, handles, options=options).solve(targets)
    assert pose.factorizations == 0
    assert np.array_equal(pose.positions[handles], targets)
    assert np.all(np.diff(pose.energies) <= 0.0)


@pytest.fixture(scope="module")
def fine_horse(horse_rings):
    """The horse at about 6,000 graph points, above Options.coarse_start_points; the region around its
    lowest point pinned, the region around its highest point dragged by a third of its size."""
    graph = solver.build_graph(horse_rings, spacing=3.0)
    assert graph.n > solver.Options().coarse_start_points
    points, size = graph.points, graph.size
    pinned = region(points, points[np.argmin(points[:, 1])], 0.06 * size)
    dragged = region(points, points[np.argmax(points[:, 1])], 0.06 * size)
    handles = np.concatenate([pinned, dragged])
    targets = points[handles].copy()
    targets[len(pinned):] += np.array([-0.25, 0.2]) * size
    return graph, handles, targets


def test_large_graph_is_converged_within_15_iterations(fine_horse):
    """The paper's constant matrix alone ends this drag about 4e-3 of the size short of the
    minimum; with Newton steps over the two-grid the default solve is within 1e-3 in at most
    15 iterations, and the fine factor is never refactorised."""
    graph, handles, targets = fine_horse
    deformer = solver.Deformer(graph, handles)
    start = deformer.solve(targets, max_iterations=0).positions  # the coarse copy's pose
    converged = solver.Deformer(graph, handles, newton=True).solve(
        targets, max_iterations=300, tolerance=1e-9, initial=start)
    assert converged.converged
    fine_factor = deformer._preconditioner._two_grid._smoother._factor
    pose = deformer.solve(targets, max_iterations=15)
    assert np.abs(pose.positions - converged.positions).max() <= 1e-3 * graph.size
    assert np.all(np.diff(pose.energies) <= 0.0)
    assert deformer._preconditioner._two_grid._smoother._factor is fine_factor
    paper = solver.Deformer(graph, handles, newton=False).solve(targets, max_iterations=15)
    assert np.abs(paper.positions - converged.positions).max() > 2e-3 * graph.size


def test_large_graph_drag_played_with_warm_starts_reaches_the_jumped_pose(fine_horse):
    """The viewport's case on a dense graph: each frame warm-started from the last, 15
    iterations each. The paper's matrix alone trails the drag there by several percent."""
    graph, handles, targets = fine_horse
    deformer = solver.Deformer(graph, handles)
    rest = graph.points[handles]
    pose = None
    for t in np.linspace(0, 1, 11)[1:]:
        pose = deformer.solve(rest + (targets - rest) * t, max_iterations=15,
                              initial=None if pose is None else pose.positions)
    jumped = deformer.solve(targets).positions
    assert np.abs(pose.positions - jumped).max() <= 1e-3 * graph.size


def test_large_graph_keeps_its_area_and_opens_its_folds(fine_horse):
    """The two-grid path with the area constraint and with the fold penalty."""
    graph, handles, targets = fine_horse
    pose = solver.Deformer(graph, handles, preserve_area=True).solve(targets)
    assert abs(graph.area(pose.positions) / graph.area() - 1.0) <= 1e-9
    assert np.all(np.diff(pose.energies) <= 0.0)
    # Hooves pinned, head pulled back: the paper's energy folds 119 triangles here.
    handles, targets, _ = hooves_and_head(graph.points)
    plain = solver.Deformer(graph, handles).solve(targets)
    pose = solver.Deformer(graph, handles, prevent_flips=True).solve(targets)
    assert flipped(graph, plain.positions) > 0
    assert flipped(graph, pose.positions) == 0
    assert np.all(np.diff(pose.energies) <= 0.0)


def test_paper_matrix_mode_never_refactorises(horse_graph, horse_drag):
    handles, targets, _ = horse_drag
    deformer = solver.Deformer(horse_graph, handles, newton=False)
    factor = deformer._preconditioner._factor
    for t in (0.3, 0.6, 1.0):
        rest = horse_graph.points[handles]
        pose = deformer.solve(rest + (targets - rest) * t)
        assert pose.factorizations == 0 and deformer._preconditioner._factor is factor
        assert np.array_equal(pose.positions[handles], rest + (targets - rest) * t)


def test_weights_that_leave_points_free_are_refused(horse_graph, horse_drag):
    handles, targets, _ = horse_drag
    with pytest.raises(solver.UncoveredPoints, match="in no energy term") as refused:
        solver.Deformer(horse_graph, handles, weights={"mvc": 0.0, "edge": 0.0})
    assert set(refused.value.terms) == {"mvc", "edge"}  # either would cover the interior
    # Without the curve term, boundary points with no inner edge (corners) are in none: only
    # the curve term covers them, and the message says so (it named the two weights given).
    # A 3 x 3 grid of quads (a mesh that is its own graph): each corner has boundary edges only.
    xs, ys = np.meshgrid(np.arange(4.0), np.arange(4.0))
    points = np.stack([xs.ravel(), ys.ravel()], axis=1)
    index = np.arange(16).reshape(4, 4)
    quads = np.stack([index[:-1, :-1], index[:-1, 1:], index[1:, 1:], index[1:, :-1]], axis=-1).reshape(-1, 4)
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    edges = np.unique(np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [0, 2]]]),
                              axis=1), axis=0)
    loop = np.array([0, 1, 2, 3, 7, 11, 15, 14, 13, 12, 8, 4])
    grid = solver.Graph(points, edges, [loop], triangles)
    with pytest.raises(solver.UncoveredPoints) as refused:
        solver.Deformer(grid, np.array([5, 6]), weights={"laplacian": 0.0})
    assert refused.value.terms == ["laplacian"] and refused.value.count >= 1
    # The message agrees with the count.
    assert "with these weights 1 point is in no energy term and nothing decides where it goes; give 'laplacian'" \
        in str(solver.UncoveredPoints(1, ["laplacian"]))
    assert "4 points are in no energy term and nothing decides where they go; give 'mvc' or 'edge'" \
        in str(solver.UncoveredPoints(4, ["mvc", "edge"]))
    # Tiny local-area weights are fine (the paper's Figure 3, right, without local area).
    pose = solver.Deformer(horse_graph, handles, weights={"mvc": 1e-3, "edge": 1e-3}).solve(targets)
    assert np.all(np.isfinite(pose.positions))


def _turned_b(lattice=450):
    """The top of a 'B' turned 90 degrees about its left side, the bottom pinned."""
    rings = glyph_rings("B")
    graph = solver.build_graph(rings, spacing=np.sqrt(solver.shapes.shape_geometry(rings).area / lattice))
    low, high = graph.points.min(axis=0), graph.points.max(axis=0)
    unit = (graph.points - low) / (high - low)
    bottom, top = np.flatnonzero(unit[:, 1] <= 0.04), np.flatnonzero(unit[:, 1] >= 0.96)
    pivot = low + np.array([0.05, 0.55]) * (high - low)
    turned = (graph.points[top] - pivot) @ rotation(np.pi / 2).T + pivot
    return graph, np.concatenate([bottom, top]), np.concatenate([graph.points[bottom], turned])


def test_prevent_flips_keeps_a_large_turn_unfolded():
    """Turning the top of a 'B' by 90 degrees folds triangles at the paper's minimum; with
    prevent_flips the pose has none, and costs little of the paper's energy to get there."""
    graph, handles, targets = _turned_b()
    deformer = solver.Deformer(graph, handles)
    plain = deformer.solve(targets)
    guarded = solver.Deformer(graph, handles, prevent_flips=True).solve(targets)
    assert flipped(graph, plain.positions) > 0
    assert flipped(graph, guarded.positions) == 0
    assert np.all(np.diff(guarded.energies) <= 0.0)
    assert np.array_equal(guarded.positions[handles], targets)
    paper_energy = deformer.energy.evaluate(guarded.positions)[0]
    assert paper_energy <= 1.15 * plain.energies[-1]


def test_fold_penalty_of_a_sliver_is_no_stiffer_than_of_a_fair_triangle():
    """A triangle's penalty stiffens as its rest area shrinks; for slivers (height far below the
    longest edge) it is bounded by that of a triangle with the same longest edge."""
    points = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1e-4], [0.5, -0.8]])
    graph = solver.Graph(points, [[0, 1], [1, 2], [2, 0], [0, 3], [3, 1]], [[0, 3, 1, 2]],
                         triangles=[[0, 1, 2], [0, 3, 1]])
    options = solver.Options()
    every_point_free = Unknowns(graph, np.array([0]))
    every_point_free.free, every_point_free.fixed = np.arange(4), np.array([], dtype=np.int64)
    penalty = FoldPenalty(graph, every_point_free, options.fold_threshold, options.fold_weight,
                          options.sliver_area)
    squeezed = points.copy()
    squeezed[[2, 3], 1] = [-1e-4, -1e-4]  # both triangles turned inside out by a hair
    coefficient, u, _ = penalty.terms(squeezed.T.ravel())
    stiffness = -coefficient * np.einsum("tk,tk->t", u, u)  # curvature along the area gradient
    longest, ratio = 1.0, -1.0  # the sliver is turned exactly inside out
    # What a triangle of area sliver_area * longest^2 turned to the same ratio would have
    # (half of E''(a) for E = w a0 (t - r)^3 / (3 t^2); solver.folds).
    bound = options.fold_weight * (options.fold_threshold - ratio) / (options.fold_threshold ** 2 * options.sliver_area * longest ** 2)
    assert stiffness[0] <= bound * np.dot(u[0], u[0]) * (1 + 1e-12)
    assert stiffness[0] < 10.0 * stiffness[1]


def test_prevent_flips_converges_where_the_boundary_is_much_denser_than_the_interior():
    """A figure built by unions, with a boundary about six times denser than its lattice: small
    triangles line it. Without the sliver bound this drag stalled at 30 iterations."""
    graph = solver.build_graph(figure_rings())
    points, size = graph.points, graph.size
    low, high = points[np.argmin(points[:, 1])], points[np.argmax(points[:, 1])]
    pinned = np.flatnonzero(np.linalg.norm(points - low, axis=1) < 0.06 * size)
    dragged = np.flatnonzero(np.linalg.norm(points - high, axis=1) < 0.06 * size)
    handles = np.concatenate([pinned, dragged])
    targets = points[handles].copy()
    targets[len(pinned):] += np.array([-0.25, 0.2]) * size
    pose = solver.Deformer(graph, handles, prevent_flips=True).solve(targets)
    assert pose.converged
    assert flipped(graph, pose.positions) == 0


def test_prevent_flips_changes_nothing_where_nothing_folds(horse_graph, horse_drag):
    """The penalty only acts on squeezed triangles: on a drag that folds none, the poses agree."""
    handles, targets, _ = horse_drag
    rest = horse_graph.points[handles]
    targets = rest + 0.5 * (targets - rest)
    plain = solver.Deformer(horse_graph, handles).solve(targets)
    guarded = solver.Deformer(horse_graph, handles, prevent_flips=True).solve(targets)
    assert flipped(horse_graph, plain.positions) == 0
    assert np.abs(guarded.positions - plain.positions).max() <= 1e-12 * horse_graph.size
    assert guarded.energies == plain.energies


def test_prevent_flips_with_exact_area_keeps_holes_open():
    """Stretching a 'B' with its area held squeezes the holes' walls until they fold; with
    prevent_flips they stay open and the area is still exact."""
    rings = glyph_rings("B")
    graph = solver.build_graph(rings, spacing=np.sqrt(solver.shapes.shape_geometry(rings).area / 3900))
    low, high = graph.points.min(axis=0), graph.points.max(axis=0)
    bottom = np.flatnonzero(graph.points[:, 1] <= low[1] + 0.04 * (high - low)[1])
    top = np.flatnonzero(graph.points[:, 1] >= high[1] - 0.04 * (high - low)[1])
    handles = np.concatenate([bottom, top])
    targets = graph.points[handles] + np.where(np.isin(handles, top)[:, None], [0.0, 0.4 * (high - low)[1]], 0.0)
    # The paper's sums as they are: at this density their bending terms have faded and the walls
    # fold without the penalty (the density-normalised energy holds them open on its own).
    plain = solver.Deformer(graph, handles, preserve_area=True, normalise_density=False).solve(targets)
    guarded = solver.Deformer(graph, handles, preserve_area=True, prevent_flips=True,
                              normalise_density=False).solve(targets)
    assert flipped(graph, plain.positions) > 0
    assert flipped(graph, guarded.positions) == 0
    assert abs(graph.area(guarded.positions) / graph.area() - 1.0) <= 1e-9


def test_a_shortened_step_is_not_taken_for_convergence():
    """Frame 24 of 30 of a linear drag that turns the top of a 'B' (the chord squeezes it):
    with the fold penalty the line search shortens steps for a while, and a short step taken
    then once stopped the solve 3e-3 of the size away from the minimum."""
    graph = solver.build_graph(glyph_rings("B"))
    low, high = graph.points.min(axis=0), graph.points.max(axis=0)
    unit = (graph.points - low) / (high - low)
    bottom, top = np.flatnonzero(unit[:, 1] <= 0.04), np.flatnonzero(unit[:, 1] >= 0.96)
    pivot = low + np.array([0.05, 0.55]) * (high - low)
    turned = (graph.points[top] - pivot) @ rotation(np.pi / 2).T + pivot
    handles = np.concatenate([bottom, top])
    targets = np.concatenate([graph.points[bottom], graph.points[top] + 0.8 * (turned - graph.points[top])])
    deformer = solver.Deformer(graph, handles, prevent_flips=True)
    converged = deformer.solve(targets, max_iterations=300, tolerance=0.0)
    pose = deformer.solve(targets)
    assert pose.converged
    assert np.abs(pose.positions - converged.positions).max() <= 1e-3 * graph.size


def test_fold_penalty_gradient_matches_finite_differences():
    from solver.folds import FoldPenalty

    graph, handles, targets = _turned_b()
    deformer = solver.Deformer(graph, handles)
    folded = deformer.solve(targets).positions
    free, fixed = deformer.free, deformer.unknowns.fixed
    options = solver.Options()
    penalty = FoldPenalty(graph, deformer.unknowns, options.fold_threshold, options.fold_weight,
                          options.sliver_area)
    penalty.hold(folded[fixed])
    v = folded[free].T.ravel()
    energy, half_gradient = penalty.evaluate(v)
    assert energy > 0.0
    rng = np.random.default_rng(3)
    for _ in range(5):
        direction = rng.normal(size=v.shape)
        step = 1e-6 * graph.size / np.abs(direction).max()
        slope = (penalty.evaluate(v + step * direction)[0] - penalty.evaluate(v - step * direction)[0]) / (2 * step)
        assert slope == pytest.approx(2.0 * half_gradient @ direction, rel=1e-4, abs=1e-9 * energy)


def test_a_rebuilt_deformer_reuses_the_coarse_copy_of_an_equal_graph(horse_graph, horse_drag):
    """Changing handles or weights rebuilds the Deformer, often on a new but equal Graph (the
    add-on rebuilds its graph from stored data): with the caller's CoarseCopies passed along, the
    coarse copy is built once, and the pose is the same as with a fresh one."""
    options = solver.Options()
    copies = solver.CoarseCopies()
    handles, targets, _ = horse_drag
    first = solver.Deformer(horse_graph, handles, coarse_copies=copies).solve(targets).positions
    again = solver.Graph(horse_graph.points.copy(), horse_graph.edges, horse_graph.boundary_loops,
                         horse_graph.triangles)
    solver.Deformer(again, handles[:-3], weights={"edge": 2.0}, coarse_copies=copies)
    copy = copies.get(horse_graph, options.coarse_interior, options.coarse_detail)
    assert copy is not None
    assert copies.get(again, options.coarse_interior, options.coarse_detail) is copy
    moved = again.points.copy()
    moved[0] += 1.0
    other = solver.Graph(moved, again.edges, again.boundary_loops, again.triangles)
    assert copies.get(other, options.coarse_interior, options.coarse_detail) is not copy
    assert np.array_equal(solver.Deformer(again, handles, coarse_copies=copies).solve(targets).positions, first)
    assert np.array_equal(solver.Deformer(again, handles).solve(targets).positions, first)


def test_the_fold_penalty_holds_each_triangle_as_firmly_at_any_density():
    """Squeezed alike, a triangle of a graph at half the default spacing (a quarter of the area)
    pays about the penalty of a triangle at the default spacing: a fold is one triangle's event,
    so a dense graph does not let small triangles fold more easily (solver.folds)."""
    turn = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    disk = [np.column_stack([np.cos(turn), np.sin(turn)])]
    reference = solver.graph.default_spacing(solver.build_graph(disk).geometry())
    per_triangle = []
    for spacing in (reference, reference / 2):
        graph = solver.build_graph(disk, spacing=spacing)
        handles = np.flatnonzero(graph.points[:, 1] < -0.9)
        deformer = solver.Deformer(graph, handles, prevent_flips=True)
        squashed = graph.points * [1.0, 0.2]  # every triangle at a fifth of its rest area
        deformer._folds.hold(squashed[deformer.unknowns.fixed])
        energy, _ = deformer._folds.evaluate(squashed[deformer.free].T.ravel())
        per_triangle.append(energy / len(graph.triangles))
    assert per_triangle[1] == pytest.approx(per_triangle[0], rel=0.3)


def test_coarse_copies_keep_the_most_recently_used():
    """A copy asked for again stays when newer ones arrive; the least recently used goes."""
    copies = solver.CoarseCopies(kept=2)
    a, b, c = (solver.build_graph([disk(r, 48)]) for r in (1.0, 1.5, 2.0))
    first = copies.get(a)
    copies.get(b)
    assert copies.get(a) is first
    copies.get(c)  # evicts b, not a
    assert copies.get(a) is first


@pytest.mark.parametrize("options", [{}, {"prevent_flips": True}, {"preserve_area": True}])
def test_an_island_held_by_one_point_is_carried_without_turning(options):
    """With one handle point an island may turn about it at no cost: the start settled the turn
    by a pull too weak to hold it, so a drag of the shape's size turned an L 139 degrees and a
    rest target came back 4e-5 off the rest. Any point, any drag (none included): the rest,
    moved rigidly, on one island and on two."""
    rng = np.random.default_rng(17)
    letter = solver.build_graph([np.array([[0, 0], [4, 0], [4, 1], [1, 1], [1, 3], [0, 3]], float)])
    pair = solver.build_graph([disk(1.0), disk(0.6, centre=(3.0, 0.0))])
    for graph, islands in ((letter, [np.arange(letter.n)]),
                           (pair, [np.flatnonzero(pair.points[:, 0] < 2.0), np.flatnonzero(pair.points[:, 0] > 2.0)])):
        rest = graph.points
        for trial in range(4):
            held = [int(rng.choice(part)) for part in islands]
            drags = rng.uniform(-1.0, 1.0, (len(islands), 2)) * graph.size * (trial > 0)
            solution = solver.Deformer(graph, held, **options).solve(rest[held] + drags)
            assert solution.converged  # QA: the free turn kept it from stopping, 30 iterations on
            for part, drag in zip(islands, drags):
                assert np.abs(solution.positions[part] - rest[part] - drag).max() <= 1e-9 * graph.size
    # Beside an island pinned and dragged at its ends, which the solve still moves.
    x = pair.points[:, 0]
    ends = np.concatenate([np.flatnonzero(x < -0.9), np.flatnonzero((x > 0.9) & (x < 2.0))])
    single = int(np.flatnonzero(x > 2.0)[0])
    handles = np.append(ends, single)
    targets = pair.points[handles] + np.where((pair.points[handles, 0] > 0.9)[:, None], [0.0, 0.5], 0.0)
    targets[-1] = pair.points[single] + [1.0, 0.3]
    solution = solver.Deformer(pair, handles, **options).solve(targets)
    assert solution.converged
    small = x > 2.0
    assert np.abs(solution.positions[small] - pair.points[small] - [1.0, 0.3]).max() <= 1e-9 * pair.size


def test_preserve_area_takes_handles_that_leave_a_coarse_copy_no_free_boundary():
    """All but one to three of a square's boundary points held: every point of its coarse copy's
    boundary lay nearest a handle, and the deformer refused, "preserve_area needs a boundary
    point that can move", though the fine graph has one (QA). The area is kept exactly."""
    graph = solver.build_graph([np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)])
    for free in (1, 2, 3):
        handles = graph.boundary[free:]
        solution = solver.Deformer(graph, handles, preserve_area=True).solve((graph.points[handles] - 0.5) * 0.9 + 0.5)
        assert graph.area(solution.positions) == pytest.approx(graph.area(), rel=1e-9)


def test_one_deformer_solving_in_two_threads_gives_each_its_own_pose():
    """Solves kept working state on the deformer while the factorisation released the
    interpreter's lock: 73-82 of 100 poses were another's, then the process crashed."""
    from concurrent.futures import ThreadPoolExecutor
    graph = solver.build_graph([np.array([[0, 0], [4, 0], [4, 1], [1, 1], [1, 3], [0, 3]], float)])
    x = graph.points[:, 0]
    handles = np.concatenate([np.flatnonzero(x < 0.2), np.flatnonzero(x > 3.8)])
    rng = np.random.default_rng(0)
    targets = [graph.points[handles] + np.where((graph.points[handles, 0] > 2)[:, None], rng.normal(0, 0.7, 2), 0)
               for _ in range(6)]
    deformer = solver.Deformer(graph, handles)
    alone = [deformer.solve(t).positions for t in targets]
    with ThreadPoolExecutor(2) as pool:
        together = list(pool.map(lambda k: deformer.solve(targets[k]).positions, list(range(6)) * 3))
    for k, pose in enumerate(together):
        assert pose.tobytes() == alone[k % 6].tobytes()


def test_a_deformer_keeps_its_own_handles():
    graph = solver.build_graph([np.array([[0, 0], [4, 0], [4, 1], [1, 1], [1, 3], [0, 3]], float)])
    handles = np.array([0, 5, 17, 100, 200])
    targets = graph.points[handles] + [[0, 0], [0, 0], [0.3, 0.2], [-0.2, 0.5], [0.1, 0.1]]
    deformer = solver.Deformer(graph, handles)
    before = deformer.solve(targets).positions
    handles[:] = [1, 6, 18, 101, 201]
    assert deformer.solve(targets).positions.tobytes() == before.tobytes()


def test_options_take_numpy_numbers_and_whole_floats_for_counts():
    """``max_iterations=30.0`` passed the check, then the solve failed on Python's own
    TypeError; a numpy integer was refused as 'not a number'."""
    options = solver.Options(max_iterations=30.0, history=np.int64(4), tolerance=np.float32(1e-4))
    assert type(options.max_iterations) is int and type(options.history) is int and type(options.tolerance) is float
    graph = solver.build_graph([disk()])
    handles = np.flatnonzero(graph.points[:, 0] < -0.8)
    assert solver.Deformer(graph, handles, options=options).solve(graph.points[handles] + 0.1).iterations <= 30
    with pytest.raises(ValueError, match="Options.max_iterations must be a whole number"):
        solver.Options(max_iterations=30.5)


@pytest.mark.parametrize("held", ["boundary", "every point"])
def test_preserve_area_with_no_boundary_point_free_is_refused(held):
    """With every point a handle it returned the targets, area and all (x4), silently."""
    graph = solver.build_graph([disk()])
    handles = graph.boundary if held == "boundary" else np.arange(graph.n)
    with pytest.raises(ValueError, match="preserve_area needs a boundary point that can move"):
        solver.Deformer(graph, handles, preserve_area=True)


@pytest.mark.parametrize("handles, weights, message", [
    (lambda g: g.points[:, 0] < -0.8, None, "got a boolean mask"),
    (lambda g: np.array([0.0, 1.7]), None, "whole numbers"),
    (lambda g: [0, 1], [1, 2, 3], "weights must be a dict"),
])
def test_common_mistakes_are_named(handles, weights, message):
    """A mask was read as 'a point given as a handle twice', 1.7 was cut to 1, a list of
    weights raised AttributeError."""
    graph = solver.build_graph([disk()])
    with pytest.raises(ValueError, match=message):
        solver.Deformer(graph, handles(graph), weights)
