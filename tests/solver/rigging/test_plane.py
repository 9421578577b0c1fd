"""solver.rigging.plane: best-fit planes, their axes, and refusing shapes that are not flat."""

import numpy as np
import pytest

from solver.rigging.plane import Plane, fit_plane


def square_3d(axes, origin=(0.0, 0.0, 0.0)):
    flat = np.array([[0, 0], [2, 0], [2, 1], [0, 1], [1, 0.5]], float)
    return np.asarray(origin) + flat @ np.asarray(axes, float)


@pytest.mark.parametrize("axes, u, v", [
    ([[1, 0, 0], [0, 1, 0]], [1, 0, 0], [0, 1, 0]),   # top view: XY
    ([[1, 0, 0], [0, 0, 1]], [1, 0, 0], [0, 0, 1]),   # front view: XZ, as grease pencil draws
    ([[0, 1, 0], [0, 0, 1]], [0, 1, 0], [0, 0, 1]),   # side view: YZ
])
def test_standard_views_come_out_upright(axes, u, v):
    plane = fit_plane(square_3d(axes, origin=(3, -2, 5)))
    np.testing.assert_allclose(plane.axes[0], u, atol=1e-12)
    np.testing.assert_allclose(plane.axes[1], v, atol=1e-12)
    np.testing.assert_allclose(np.cross(plane.axes[0], plane.axes[1]), plane.normal, atol=1e-12)


def test_round_trip_with_heights_is_exact_for_a_tilted_plane():
    rotation = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))[0]
    points = square_3d(rotation[:2], origin=(1, 2, 3))
    plane = fit_plane(points)
    flat = plane.to_2d(points)
    np.testing.assert_allclose(plane.to_3d(flat, plane.heights(points)), points, atol=1e-14)
    np.testing.assert_allclose(np.abs(plane.heights(points)), 0, atol=1e-12)
    # 2D distances are 3D distances.
    np.testing.assert_allclose(np.linalg.norm(flat[1] - flat[0]), 2.0)


def test_stored_plane_round_trips():
    plane = fit_plane(square_3d([[1, 0, 0], [0, 0, 1]]))
    again = Plane.from_array(plane.to_array())
    np.testing.assert_array_equal(again.axes, plane.axes)
    np.testing.assert_array_equal(again.origin, plane.origin)


def test_not_planar_says_how_far():
    points = square_3d([[1, 0, 0], [0, 1, 0]])
    points[4, 2] = 0.3
    with pytest.raises(ValueError, match=r"not planar.*0\.2"):
        fit_plane(points)


@pytest.mark.parametrize("points, message", [
    (np.empty((0, 3)), "no points"),
    (np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2.0]]), "one line"),
    (np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0.0]]), "no area"),
    (np.array([[0, 0, np.nan], [1, 0, 0], [0, 1, 0.0]]), "non-finite"),
])
def test_degenerate_points_are_refused(points, message):
    with pytest.raises(ValueError, match=message):
        fit_plane(points)


@pytest.mark.parametrize("points", [np.array([[0, 0, 0], [1, 0, 0.5], [2, 0, 1.0]]), np.array([[0, 0, 0], [2, 0, 1.0]])])
def test_points_on_a_line_take_the_plane_through_it_nearest_the_one_given(points):
    # A straight stroke drawn in the XZ plane: on a line, which the XZ plane contains.
    plane = fit_plane(points, line_normal=(0.0, 1.0, 0.0))
    assert abs(plane.axes[2] @ [0.0, 1.0, 0.0]) == pytest.approx(1.0)
    np.testing.assert_allclose(plane.to_3d(plane.to_2d(points)), points, atol=1e-12)
    # A normal along the line itself still gives a plane through the line.
    plane = fit_plane(points, line_normal=(2.0, 0.0, 1.0))
    assert abs(plane.axes[2] @ (points[-1] - points[0])) < 1e-12
    with pytest.raises(ValueError, match="one place"):
        fit_plane(np.zeros((3, 3)), line_normal=(0.0, 1.0, 0.0))


def test_transform_points():
    from solver.rigging.plane import transform_points
    matrix = np.eye(4)
    matrix[:3, 3] = [1, 2, 3]
    matrix[0, 0] = 2.0
    np.testing.assert_allclose(transform_points(matrix, [[1, 1, 1.0]]), [[3, 3, 4]])
