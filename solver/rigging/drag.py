"""Geometry of dragging a handle with the mouse: rays, planes and picking.

The viewport turns the mouse position into a ray (an origin and a direction in world space).
A drag happens on the rig's plane: the ray meets the plane at a *hit* point, the nearest handle
(or point of the shape) to the first hit is grabbed, and as the mouse moves the grabbed thing
follows the hit point by the same offset it had when grabbed, so it does not jump to the mouse.
All arrays are float64 numpy arrays in world space unless said otherwise.
"""

from __future__ import annotations

import numpy as np

from .plane import transform_points  # noqa: F401  (the drag maps points with it too)

__all__ = ["world_plane", "ray_plane", "transform_points", "nearest", "above_every_layer", "parent_offset"]

# A ray closer than this to parallel with the plane (cosine of the angle between the ray and the
# plane's normal) meets it too far away to be useful: the drag waits for a better mouse position.
PARALLEL_COSINE = 1e-6


def world_plane(matrix_world, origin, normal):
    """A plane given in an object's local space, in world space.

    Parameters
    ----------
    matrix_world : (4, 4) array_like
        The object's world matrix (may scale unevenly or shear).
    origin, normal : (3,) array_like
        A point of the plane and its normal, in the object's local space.

    Returns
    -------
    origin, normal : (3,) float64 ndarray
        The normal has unit length.

    Raises
    ------
    ValueError
        The matrix flattens space (zero scale), so the plane has no world position.
    """
    matrix = np.asarray(matrix_world, dtype=np.float64)
    linear = matrix[:3, :3]
    if abs(np.linalg.det(linear)) <= 1e-12 * max(float(np.abs(linear).max()), 1e-300) ** 3:
        raise ValueError("the object's scale is zero, so its plane cannot be dragged on")
    point = linear @ np.asarray(origin, dtype=np.float64) + matrix[:3, 3]
    # Normals transform by the inverse transpose (the matrix may scale unevenly).
    direction = np.linalg.solve(linear.T, np.asarray(normal, dtype=np.float64))
    return point, direction / np.linalg.norm(direction)


def ray_plane(ray_origin, ray_direction, plane_origin, plane_normal):
    """Where the line through ``ray_origin`` along ``ray_direction`` meets a plane.

    The whole line counts, not only the half in front of the origin: an orthographic view
    places its ray origins far out on either side of the scene.

    Returns
    -------
    (3,) float64 ndarray or None
        None when the ray is parallel to the plane (looking at it edge-on) or not finite.
    """
    origin = np.asarray(ray_origin, dtype=np.float64)
    direction = np.asarray(ray_direction, dtype=np.float64)
    normal = np.asarray(plane_normal, dtype=np.float64)
    length = float(np.linalg.norm(direction))
    if not np.isfinite(length) or length == 0.0:
        return None
    facing = float(direction @ normal) / length
    if not abs(facing) > PARALLEL_COSINE:
        return None
    t = float((np.asarray(plane_origin, dtype=np.float64) - origin) @ normal) / float(direction @ normal)
    hit = origin + t * direction
    return hit if np.all(np.isfinite(hit)) else None


def nearest(points, query):
    """Index of the point (p, 3) nearest to ``query`` (3,), or -1 when there are no points."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0:
        return -1
    distance = np.linalg.norm(points - np.asarray(query, dtype=np.float64), axis=1)
    distance[~np.isfinite(distance)] = np.inf
    return int(np.argmin(distance))


def above_every_layer(point, shape, normal):
    """``point`` (3,) lifted along the plane's ``normal`` (3,) past every point of ``shape``
    (p, 3), the shape as shown, whose layers are lifted along it where the pose overlaps
    itself: a handle added there goes on the layer in front (the one lifted furthest along
    ``normal``, which a view from that side shows), where a layer left on the plane would
    otherwise be as near as the one over it."""
    shape = np.asarray(shape, dtype=np.float64).reshape(-1, 3)
    reach = float(np.ptp(shape, axis=0).max()) if len(shape) else 0.0
    return np.asarray(point, dtype=np.float64) + reach * np.asarray(normal, dtype=np.float64)


def parent_offset(parent_matrix, offset):
    """A world-space displacement expressed in a child's parent space.

    A child's ``location`` lives in the space of ``parent_matrix`` (its parent's world matrix
    times its parent-inverse matrix, or the identity without a parent): moving the child by the
    world vector ``offset`` means adding the returned vector to its location.

    Parameters
    ----------
    parent_matrix : (4, 4) array_like
    offset : (3,) array_like

    Returns
    -------
    (3,) float64 ndarray

    Raises
    ------
    ValueError
        The parent space is flat (zero scale): no location reaches the offset.
    """
    linear = np.asarray(parent_matrix, dtype=np.float64)[:3, :3]
    try:
        local = np.linalg.solve(linear, np.asarray(offset, dtype=np.float64))
    except np.linalg.LinAlgError:
        raise ValueError("the handle's parent has zero scale, so the handle cannot be moved") from None
    if not np.all(np.isfinite(local)):
        raise ValueError("the handle's parent has zero scale, so the handle cannot be moved")
    return local
