"""solver.rigging.drag: rays meeting the rig's plane, picking, and moving a parented handle."""

import numpy as np
import pytest

from solver.rigging.drag import nearest, parent_offset, ray_plane, transform_points, world_plane


def test_ray_meets_plane_on_either_side_of_its_origin():
    hit = ray_plane([1.0, 2.0, 5.0], [0, 0, -2.0], [0, 0, 1.0], [0, 0, 1.0])
    np.testing.assert_allclose(hit, [1, 2, 1])
    # Orthographic views put ray origins beyond the plane too.
    behind = ray_plane([1.0, 2.0, -5.0], [0, 0, -1.0], [0, 0, 1.0], [0, 0, 1.0])
    np.testing.assert_allclose(behind, [1, 2, 1])


def test_oblique_ray_hits_a_tilted_plane_on_the_plane():
    normal = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    origin = np.array([0.3, 0.1, -0.2])
    hit = ray_plane([4.0, 3.0, 2.0], [-1.0, -0.5, -0.7], origin, normal)
    assert (hit - origin) @ normal == pytest.approx(0.0, abs=1e-12)
    assert np.linalg.norm(np.cross(hit - [4.0, 3.0, 2.0], [-1.0, -0.5, -0.7])) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("direction", [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [np.nan, 0.0, 1.0]])
def test_edge_on_or_bad_rays_miss(direction):
    assert ray_plane([0, 0, 1.0], direction, [0, 0, 0], [0, 0, 1.0]) is None


def test_world_plane_follows_uneven_scale_and_rotation():
    angle = 0.4
    rotation = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    matrix = np.eye(4)
    matrix[:3, :3] = rotation @ np.diag([3.0, 1.0, 0.5])
    matrix[:3, 3] = [1, 2, 3]
    local_origin, local_normal = np.array([0.2, 0.1, 0.0]), np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    origin, normal = world_plane(matrix, local_origin, local_normal)
    # Two in-plane local directions stay perpendicular to the world normal.
    for tangent in ([1.0, -1.0, 0.0], [0.0, 0.0, 1.0]):
        assert (matrix[:3, :3] @ tangent) @ normal == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(origin, transform_points(matrix, local_origin)[0])
    assert np.linalg.norm(normal) == pytest.approx(1.0)


def test_world_plane_refuses_zero_scale():
    with pytest.raises(ValueError, match="scale is zero"):
        world_plane(np.diag([1.0, 0.0, 1.0, 1.0]), [0, 0, 0], [0, 0, 1.0])


def test_nearest_ignores_non_finite_points_and_handles_empty():
    points = np.array([[0, 0, 0], [np.nan, 0, 0], [2, 0, 0.0]])
    assert nearest(points, [1.5, 0.0, 0.0]) == 2
    assert nearest(np.empty((0, 3)), [0, 0, 0]) == -1


def test_parent_offset_moves_a_child_by_the_world_offset():
    parent = np.eye(4)
    parent[:3, :3] = np.array([[0, -2.0, 0], [2.0, 0, 0], [0, 0, 2.0]])
    parent[:3, 3] = [5, 6, 7]
    location = np.array([0.1, 0.2, 0.3])
    offset = np.array([0.5, -1.0, 0.25])
    moved = location + parent_offset(parent, offset)
    np.testing.assert_allclose(transform_points(parent, moved) - transform_points(parent, location), [offset])
    with pytest.raises(ValueError, match="zero scale"):
        parent_offset(np.diag([0.0, 1.0, 1.0, 1.0]), offset)
