"""solver.rigging.handles: frames of handles, regions, and targets that carry regions."""

import numpy as np
import pytest

import solver
from solver.rigging.handles import (apply_affine, distance_off, frame_2d, handle_matrix, invert_affine,
                                    region_offsets, region_targets, rest_position, select_region)
from solver.rigging.plane import fit_plane

from sample_shapes import disk


@pytest.fixture
def xz_plane():
    return fit_plane(np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1.0]]))


def test_handle_matrix_frame_round_trip(xz_plane):
    matrix = handle_matrix(xz_plane, [0.25, 0.75], scale=2.0)
    frame = frame_2d(xz_plane, matrix)
    np.testing.assert_allclose(frame, [[2, 0, 0.25], [0, 2, 0.75], [0, 0, 1]], atol=1e-12)


def test_turning_the_handle_about_the_normal_turns_its_frame(xz_plane):
    matrix = handle_matrix(xz_plane, [0.0, 0.0])
    angle = 0.3
    c, s = np.cos(angle), np.sin(angle)
    # A rotation about the plane normal, written in 3D.
    n = xz_plane.normal
    k = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    turn = np.eye(4)
    turn[:3, :3] = np.eye(3) + s * k + (1 - c) * k @ k
    frame = frame_2d(xz_plane, turn @ matrix)
    np.testing.assert_allclose(frame[:2, :2], [[c, -s], [s, c]], atol=1e-12)


def test_offsets_and_targets_carry_a_region():
    points = np.array([[0, 0], [1, 0], [0, 1.0]])
    rest = np.eye(3)
    offsets = region_offsets(rest, points)
    moved = np.array([[0, -1, 5], [1, 0, 2], [0, 0, 1.0]])  # a quarter turn and a shift
    targets = region_targets(moved[None], offsets, np.zeros(3, int))
    np.testing.assert_allclose(targets, apply_affine(moved, points))
    np.testing.assert_allclose(targets[1], [5, 3])


def test_degenerate_frame_is_refused():
    with pytest.raises(ValueError, match="degenerate"):
        invert_affine(np.diag([1.0, 0.0, 1.0]))


def test_select_region_respects_radius_minimum_and_taken():
    points = disk(1.0, 32)
    region = select_region(points, points[0], radius=1e-6)
    assert len(region) == 3 and region[0] == 0
    big = select_region(points, [0, 0], radius=2.0)
    assert len(big) == 32
    taken = np.zeros(32, bool)
    taken[:2] = True
    region = select_region(points, points[0], radius=0.3, taken=taken)
    assert not np.isin([0, 1], region).any()
    with pytest.raises(ValueError, match="already belongs"):
        select_region(points, [0, 0], 1.0, taken=np.ones(32, bool))


def grid(nx, ny, width, height, x0, y0, first=0):
    """A grid of ``nx`` by ``ny`` squares, each cut in two: points (p, 2) rounded to 1e-12 (so
    grids share places exactly), triangles (t, 3) numbered from ``first``."""
    x, y = np.meshgrid(np.linspace(x0, x0 + width, nx + 1), np.linspace(y0, y0 + height, ny + 1))
    corner = (np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)).ravel() + first
    a, b, c, d = corner, corner + 1, corner + nx + 2, corner + nx + 1
    triangles = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return np.round(np.column_stack([x.ravel(), y.ravel()]), 12), triangles


def puppet():
    """A body (2 x 1) and an arm lying over it to x = 3, some of its points on the body's:
    points (n, 2), triangles, each point's piece (0: body, 1: arm)."""
    (body, body_triangles), (arm, arm_triangles) = grid(8, 4, 2.0, 1.0, 0.0, 0.0), \
        grid(6, 2, 1.8, 0.4, 1.2, 0.3, first=45)
    return (np.concatenate([body, arm]), np.concatenate([body_triangles, arm_triangles]),
            np.repeat([0, 1], [len(body), len(arm)]))


def test_a_region_stays_on_the_piece_of_the_point_nearest_its_centre():
    """Two pieces lying over one another (a puppet's arm over its body): a region centred on
    the arm takes none of the body's points, however large its radius, and when the arm's
    points are all taken it says so rather than taking the body's."""
    points, _, pieces = puppet()
    body, arm = points[pieces == 0], points[pieces == 1]
    elbow = len(body) + 2  # at (1.8, 0.3), 0.07 from the body's point (1.75, 0.25)
    assert np.any(pieces[select_region(points, points[elbow], 0.2)] == 0)  # without pieces: both
    for centre in points[[elbow, len(body), -1]]:
        for radius in (0.0, 0.2, 10.0):
            region = select_region(points, centre, radius, pieces=pieces)
            assert np.all(pieces[region] == 1), (centre, radius)
            assert len(region) >= 3
    assert len(select_region(points, points[elbow], 10.0, pieces=pieces)) == len(arm)
    with pytest.raises(ValueError, match="every point of this piece of the shape already belongs"):
        select_region(points, points[elbow], 0.2, taken=pieces == 1, pieces=pieces)


def test_a_region_stays_on_the_piece_it_is_given_where_pieces_share_a_place():
    """An arm point lying exactly on a body point: the nearest point is a tie, which the body's
    (the lower index) won, so a handle at the arm's point took the body. Given the arm's piece,
    the region is the arm's, nearest first."""
    points, _, pieces = puppet()
    shared = np.flatnonzero(np.all(points == [1.5, 0.5], axis=1))
    assert pieces[shared].tolist() == [0, 1]
    assert np.all(pieces[select_region(points, points[shared[1]], 0.2, pieces=pieces)] == 0)
    for radius in (0.0, 0.2, 10.0):
        region = select_region(points, points[shared[1]], radius, pieces=pieces, piece=1)
        assert region[0] == shared[1] and np.all(pieces[region] == 1), radius
    region = select_region(points, points[shared[1]], 0.0, minimum=1, pieces=pieces, piece=0)
    assert region.tolist() == [shared[0]]


def test_place_gives_the_triangle_of_the_layer_in_front():
    """Over the overlap of two pieces, the handle lies on the triangle of the layer in front
    (lifted highest; a location on the plane is under both), whose piece it is on; placed on
    the rest shape or off the shape, or without heights, no triangle is known."""
    from solver.rigging.handles import place

    points, triangles, pieces = puppet()
    plane = fit_plane(np.column_stack([points, np.zeros(len(points))]))
    flat = plane.to_2d(np.column_stack([points, np.zeros(len(points))]))
    shared = np.flatnonzero(np.all(points == [1.5, 0.5], axis=1))
    location = [1.5, 0.5, 0.0]
    for front in (0, 1):
        heights = np.where(pieces == front, 0.02, 0.01)
        _, centre, triangle = place(plane, np.eye(4), location, flat, flat, triangles, posed_heights=heights)
        assert pieces[triangles[triangle]].tolist() == [front] * 3
        np.testing.assert_allclose(centre, flat[shared[0]], atol=1e-12)
        region = select_region(flat, centre, 0.2, pieces=pieces, piece=pieces[triangles[triangle, 0]])
        assert region[0] == shared[front]
    assert place(plane, np.eye(4), location, flat, flat, triangles, on_rest=True, posed_heights=heights)[2] is None
    assert place(plane, np.eye(4), [5.0, 0.5, 0.0], flat, flat, triangles, posed_heights=heights)[2] is None
    assert place(plane, np.eye(4), location, flat, flat, triangles)[2] is None


def test_a_point_of_a_layers_outline_goes_on_that_layer_though_rounding_puts_it_off():
    """A vertex of the arm's outline over the body, read back from float32 places, lies off the
    arm's triangles by rounding and well inside the body's: at the arm's height it goes on the
    arm (it went on the body, the only layer found there)."""
    from solver.rigging.handles import place

    points, triangles, pieces = puppet()
    shape = np.column_stack([points, np.zeros(len(points))])
    plane = fit_plane(shape)
    flat = plane.to_2d(shape)
    heights = np.where(pieces == 1, 0.02, 0.0)
    arm_outline = np.flatnonzero((pieces == 1) & np.isclose(points[:, 1], 0.3) & (points[:, 0] < 1.95))
    assert len(arm_outline) >= 2
    for k in arm_outline:
        off = points[k] - [0.0, 1e-6]  # out of the arm, by less than float32 rounds at this size
        location = np.array([*off, 0.02])
        _, _, triangle = place(plane, np.eye(4), location, flat, flat, triangles, posed_heights=heights)
        assert triangle is not None and pieces[triangles[triangle, 0]] == 1, k


def test_a_location_lifted_in_front_of_the_shape_goes_on_the_layer_in_front():
    """Where one piece is left on the plane and the other lifted over it, a location on the
    plane is nearest the one left there; lifted past every point (drag.in_front) it goes on
    the one in front, whichever that is. Off the shape, ``snap`` puts it on the nearest point."""
    from solver.rigging.drag import above_every_layer
    from solver.rigging.handles import place

    points, triangles, pieces = puppet()
    shape = np.column_stack([points, np.zeros(len(points))])
    plane = fit_plane(shape)
    flat = plane.to_2d(shape)
    for front in (0, 1):
        heights = np.where(pieces == front, 0.02, 0.0)
        shown = plane.to_3d(flat, heights)
        on_plane = np.array([1.5, 0.5, 0.0])
        _, _, triangle = place(plane, np.eye(4), on_plane, flat, flat, triangles, posed_heights=heights)
        assert pieces[triangles[triangle, 0]] != front  # on the plane: the piece left there
        lifted = above_every_layer(on_plane, shown, plane.normal)
        point, _, triangle = place(plane, np.eye(4), lifted, flat, flat, triangles, posed_heights=heights)
        assert pieces[triangles[triangle, 0]] == front
        np.testing.assert_allclose(plane.to_3d(point[None])[0], on_plane, atol=1e-12)
    off = np.array([9.0, 0.6, 0.0])
    point, centre, triangle = place(plane, np.eye(4), off, flat, flat, triangles, posed_heights=heights, snap=True)
    nearest = np.argmin(np.linalg.norm(points - off[:2], axis=1))
    assert triangle is None and np.array_equal(point, flat[nearest]) and np.array_equal(centre, flat[nearest])


def test_where_parts_overlap_level_the_handle_goes_on_the_last_part():
    """At rest the arm lies level with the body (no depth yet): a location over both, on the
    plane or lifted in front, goes on the last part (a drawing's top layer), not on whichever
    triangle comes first; a body lifted 1e-3 in front, more than rounding, is in front."""
    from solver.rigging.drag import above_every_layer
    from solver.rigging.handles import place

    points, triangles, pieces = puppet()
    shape = np.column_stack([points, np.zeros(len(points))])
    plane = fit_plane(shape)
    flat = plane.to_2d(shape)
    on_plane = np.array([1.5, 0.5, 0.0])
    for heights in (np.zeros(len(points)), np.full(len(points), 0.01)):
        for location in (on_plane, above_every_layer(on_plane, plane.to_3d(flat, heights), plane.normal)):
            _, _, triangle = place(plane, np.eye(4), location, flat, flat, triangles, posed_heights=heights)
            assert pieces[triangles[triangle, 0]] == 1
    body_in_front = np.where(pieces == 0, 1e-3, 0.0)
    lifted = above_every_layer(on_plane, plane.to_3d(flat, body_in_front), plane.normal)
    _, _, triangle = place(plane, np.eye(4), lifted, flat, flat, triangles, posed_heights=body_in_front)
    assert pieces[triangles[triangle, 0]] == 0


@pytest.mark.parametrize("scale, offset", [(1.0, 0.0), (0.1, 0.0), (1.0, 1e3), (7.3, -40.0)])
def test_select_region_takes_every_point_tied_with_the_last(scale, offset):
    """On a grid a vertex's four neighbours are equally near: a region of at least three takes
    all of them, whatever the grid's size and place (rounding picked two by the scale), also
    from float32 coordinates, whose rounding differs from neighbour to neighbour."""
    x, y = np.meshgrid(np.arange(5.0), np.arange(5.0))
    points = (np.column_stack([x.ravel(), y.ravel()]) * scale + offset).astype(np.float32)
    region = select_region(points, points[12], radius=1e-6)
    assert sorted(region.tolist()) == [7, 11, 12, 13, 17]


def test_rest_position_inverts_a_pose():
    graph = solver.build_graph([disk(1.0, 48)])
    posed = graph.points * [2.0, 1.0] + [3.0, 0.0]
    query = np.array([[3.5, 0.2], [2.0, -0.4]])
    np.testing.assert_allclose(rest_position(graph.points, posed, graph.triangles, query),
                               [[0.25, 0.2], [-0.5, -0.4]], atol=1e-12)


def test_place_finds_the_rest_point_under_a_posed_location_and_back():
    """On a shape moved as a whole, a location on the posed shape is over the rest point it
    came from, and a rest location (a selected vertex) is placed where that point is now; a
    space that flattens the plane and a non-finite location are refused by name."""
    from solver.rigging.handles import place

    rest = disk(1.0, 24)
    graph = solver.build_graph([rest])
    posed = graph.points + [0.5, -0.25]
    plane = fit_plane(np.column_stack([rest, np.zeros(len(rest))]))
    world = np.eye(4)
    location = np.array([0.6, -0.2, 0.0])
    point, centre, _ = place(plane, world, location, graph.points, posed, graph.triangles)
    np.testing.assert_allclose(plane.to_3d(point[None])[0], location, atol=1e-12)
    np.testing.assert_allclose(plane.to_3d(centre[None])[0], location - [0.5, -0.25, 0.0], atol=1e-9)
    point, centre, _ = place(plane, world, location, graph.points, posed, graph.triangles, on_rest=True)
    np.testing.assert_allclose(plane.to_3d(point[None])[0], location + [0.5, -0.25, 0.0], atol=1e-9)
    with pytest.raises(ValueError, match="scaled to zero"):
        place(plane, np.diag([0.0, 1.0, 1.0, 1.0]), location, graph.points, posed, graph.triangles)
    with pytest.raises(ValueError, match="not a finite point"):
        place(plane, world, [np.inf, 0.0, 0.0], graph.points, posed, graph.triangles)


def test_distance_off_is_zero_anywhere_on_a_face_and_measured_to_the_outline_off_it():
    # One square of two triangles, 2 wide: its middle is far from every corner, yet on it.
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    for triangles in ([[0, 1, 2], [0, 2, 3]], [[0, 2, 1], [0, 3, 2]]):  # either winding
        assert distance_off(square, triangles, [1.0, 1.0]) == 0.0
        assert distance_off(square, triangles, [1.9, 0.1]) == 0.0
        assert distance_off(square, triangles, [3.0, 1.0]) == pytest.approx(1.0)
        assert distance_off(square, triangles, [3.0, 3.0]) == pytest.approx(np.sqrt(2.0))
