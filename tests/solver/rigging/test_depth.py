"""Depth for overlapping layers: the automatic score and overlap pins' reach (solver.rigging.depth)."""

import numpy as np

from solver.rigging import depth


def test_a_shape_that_only_moved_as_a_whole_stays_in_its_plane():
    rng = np.random.default_rng(3)
    rest = rng.random((40, 2))
    score = depth.moved_score(rest, rest + [0.7, -0.2], size=1.4)
    np.testing.assert_allclose(depth.heights(score, 1.4), 0.0, atol=1e-15)


def test_what_moved_further_is_higher_and_heights_scale_with_size():
    rest = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    posed = rest + [[0.0, 0.0], [0.0, 0.5], [0.0, 1.5]]
    for size in (1.0, 10.0):
        h = depth.heights(depth.moved_score(rest, posed, size), size)
        assert h[0] == 0.0 and h[0] < h[1] < h[2]
        np.testing.assert_allclose(
            h, depth.HEIGHT_PER_SCORE * np.tanh(depth.AUTO_WEIGHT * np.array([0.0, 0.5, 1.5]) * 1.0 / size) * size)


def test_however_far_a_handle_goes_the_automatic_lift_stays_below_a_pins():
    """A handle keyed a million sizes away lifted its part 10,000 sizes off the plane; the lift
    now stays below what one overlap pin at 1 gives, and still orders what moved further."""
    rest = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    posed = rest + [[0.0, 0.0], [0.0, 3.0], [0.0, 1e6]]
    h = depth.heights(depth.moved_score(rest, posed, 2.0), 2.0)
    assert 0.0 == h[0] < h[1] < h[2] <= depth.HEIGHT_PER_SCORE * 2.0


def two_strips():
    """Two parallel strips of points a small gap apart, each a chain of edges."""
    xs = np.linspace(0.0, 1.0, 11)
    points = np.concatenate([np.column_stack([xs, np.zeros(11)]), np.column_stack([xs, np.full(11, 0.05)])])
    edges = np.concatenate([np.column_stack([np.arange(10), np.arange(1, 11)]),
                            np.column_stack([np.arange(11, 21), np.arange(12, 22)])])
    return points, edges


def test_a_pin_reaches_through_the_shape_not_across_a_gap():
    points, edges = two_strips()
    weights = depth.pin_weights(points, edges, pins=[5], extents=[0.25])
    assert weights.shape == (1, 22)
    assert weights[0, 5] == 1.0
    assert np.all(weights[0, 11:] == 0.0)  # the other strip is 0.05 away across the gap
    np.testing.assert_allclose(weights[0, [4, 6]], weights[0, 4])  # symmetric along the strip
    assert weights[0, 4] == 1.0 and 1.0 > weights[0, 3] > 0.0  # full reach, then a soft edge
    assert weights[0, 2] == weights[0, 1] == 0.0  # 0.3 away: beyond the extent


def test_a_pin_reaches_only_points_near_the_graph_points_it_weighs():
    """Pin at x = 0.5 reaching 0.25 (graph points 0.3-0.7 weighed): an object's points near
    them are reached, its corners at the strip's ends are not, nor is an empty object."""
    points, edges = two_strips()
    ends = np.array([[0.0, 0.0], [1.0, 0.0]])
    assert not depth.pin_reaches(points, edges, 5, 0.25, ends, near=0.1)
    assert depth.pin_reaches(points, edges, 5, 0.25, np.vstack([ends, [0.62, 0.01]]), near=0.1)
    assert depth.pin_reaches(points, edges, 5, 0.25, ends, near=0.4)
    assert not depth.pin_reaches(points, edges, 5, 0.25, np.zeros((0, 2)), near=0.1)


def test_pins_add_up_where_their_extents_meet_and_sign_sets_front_or_back():
    points, edges = two_strips()
    weights = depth.pin_weights(points, edges, pins=[3, 6], extents=[0.5, 0.5])
    score = np.zeros(22)
    both = depth.heights(score, 1.0, [1.0, 1.0], weights)
    assert both[4] > depth.heights(score, 1.0, [1.0, 0.0], weights)[4] > 0.0
    assert np.all(depth.heights(score, 1.0, [-1.0, 0.0], weights)[:10] <= 0.0)


def test_reach_tints_follow_the_summed_amounts():
    """White where overlap pins add up to in front, black behind, opacity capped at 1 of amount;
    starch after them, as opaque as its stiffness; points no pin reaches are left out."""
    overlap = np.array([[1.0, 1.0, 0.0, 0.0], [0.0, 1.0, 1.0, 0.0]])
    points, colors = depth.reach_tints([0.5, -2.0], overlap, [5.0], [[0.0, 0.0, 0.0, 1.0]],
                                       opacity=0.8, starch_color=(0.0, 0.0, 1.0, 0.6))
    assert points.tolist() == [0, 1, 2, 3]
    assert colors[0, :3].tolist() == [1, 1, 1] and np.isclose(colors[0, 3], 0.4)
    assert colors[1, :3].tolist() == [0, 0, 0] and np.isclose(colors[1, 3], 0.8)  # -1.5: capped
    assert colors[2, :3].tolist() == [0, 0, 0] and np.isclose(colors[2, 3], 0.8)
    assert colors[3, :3].tolist() == [0, 0, 1] and np.isclose(colors[3, 3], 0.3)  # 5 of 10
    assert depth.stiffness([], np.zeros((0, 4))) is None
    assert np.allclose(depth.stiffness([5.0], [[0.0, 0.0, 0.0, 1.0]]), [1, 1, 1, 6])


def test_the_automatic_order_reaches_only_where_the_pose_overlaps_itself():
    """A strip bent into a U is lifted nowhere (nothing overlaps: a lift pushed it through an
    object set just in front); folded back over itself, the overlap and its surroundings get
    the order, and the far end none."""
    from solver import build_graph

    graph = build_graph([np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 1.0], [0.0, 1.0]])])
    rest, size = graph.points, graph.size
    lengths = depth.edge_lengths(rest, graph.edges)

    def bent(angle_per_unit):  # the strip's x wound round a circle, its y the radius's change
        theta = angle_per_unit * rest[:, 0]
        radius = 1.0 / angle_per_unit + rest[:, 1]
        return np.column_stack([radius * np.sin(theta), 1.0 / angle_per_unit - radius * np.cos(theta)])

    u_shape = bent(np.pi / 4.0)  # half a turn over the strip's length: no overlap
    np.testing.assert_array_equal(depth.automatic_reach(u_shape, graph.triangles, lengths, size), 0.0)
    np.testing.assert_array_equal(depth.automatic_reach(rest, graph.triangles, lengths, size), 0.0)
    folded = bent(2.4 * np.pi / 4.0)  # 1.2 turns: the end comes back over the start
    reach = depth.automatic_reach(folded, graph.triangles, lengths, size)
    assert reach.max() == 1.0 and np.all((reach >= 0.0) & (reach <= 1.0))
    middle = np.abs(rest[:, 0] - 2.0) < 0.2
    assert np.all(reach[middle] == 0.0) and np.all(reach[rest[:, 0] < 0.2] == 1.0)
