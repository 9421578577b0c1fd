"""Handles as the animator sees them: a movable frame that carries a small region of the shape.

A handle is an object with a transform (in Blender an Empty). It owns a few graph points near
it, its *region*, so dragging it moves a patch of the shape rather than spiking one vertex, and
turning or scaling it turns or scales that patch. Each region point is stored as an *offset* in
the handle's own 2D frame; the targets given to the deformer are those offsets carried by the
handle's current frame. Frames are 2D affine maps, 3x3 matrices acting on ``(x, y, 1)``.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..binding import bind
from .plane import affine_inverse, transform_points

__all__ = ["frame_2d", "handle_matrix", "apply_affine", "invert_affine", "select_region",
           "region_offsets", "region_targets", "rest_position", "place", "distance_off"]
# Fewest graph points in a region: three points fix a patch's rotation as well as its place.
MIN_REGION_POINTS = 3
# Relative difference of distances that counts as a tie: above float32's rounding (1.2e-7),
# which a mesh's vertices carry.
TIE = 1e-5


def frame_2d(plane, matrix):
    """The 2D frame of a handle: its origin and X, Y axes projected into the plane.

    Parameters
    ----------
    plane : solver.rigging.plane.Plane
        The shape's plane, in the same space as ``matrix`` (the space the shape was
        bound in).
    matrix : (4, 4) array_like
        The handle's transform in that space.

    Returns
    -------
    (3, 3) float64 ndarray
        Affine map from handle coordinates to plane coordinates.
    """
    matrix = np.asarray(matrix, dtype=np.float64)
    frame = np.eye(3)
    frame[:2, :2] = plane.axes[:2] @ matrix[:3, :2]
    frame[:2, 2] = plane.to_2d(matrix[None, :3, 3])[0]
    return frame


def handle_matrix(plane, point, scale=1.0):
    """Transform of a handle placed at plane ``point`` with its X, Y axes along the plane's.

    Parameters
    ----------
    plane : solver.rigging.plane.Plane
    point : (2,) array_like
        Position in plane coordinates.
    scale : float
        Length of the handle's axes.

    Returns
    -------
    (4, 4) float64 ndarray
        In the plane's 3D space; its Z axis is the plane's normal.
    """
    matrix = np.eye(4)
    matrix[:3, :3] = scale * plane.axes.T
    matrix[:3, 3] = plane.to_3d(np.asarray(point, dtype=np.float64)[None])[0]
    return matrix


def apply_affine(affine, points):
    """Apply 3x3 affine map(s) to 2D points.

    Parameters
    ----------
    affine : (3, 3) or (p, 3, 3) array_like
        One map for all points, or one per point.
    points : (p, 2) array_like

    Returns
    -------
    (p, 2) float64 ndarray
    """
    affine = np.asarray(affine, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    if affine.ndim == 2:
        return points @ affine[:2, :2].T + affine[:2, 2]
    return np.einsum("pij,pj->pi", affine[:, :2, :2], points) + affine[:, :2, 2]


def invert_affine(affine):
    """Inverse of a 3x3 affine map; ValueError if it flattens the plane (a zero-scale handle)."""
    affine = np.asarray(affine, dtype=np.float64)
    determinant = float(np.linalg.det(affine[:2, :2]))
    scale = float(np.abs(affine[:2, :2]).max())
    if not np.isfinite(determinant) or abs(determinant) <= 1e-12 * max(scale, 1e-300) ** 2:
        raise ValueError("the handle's frame is degenerate (zero scale, or turned edge-on to the plane)")
    return np.linalg.inv(affine)


def select_region(points, centre, radius, taken=None, minimum=MIN_REGION_POINTS, pieces=None, piece=None):
    """Graph points a handle at ``centre`` owns.

    Parameters
    ----------
    points : (n, 2) array_like
        Graph points (rest positions).
    centre : (2,) array_like
    radius : float
        Points closer than this belong to the region; if fewer than ``minimum`` are, the
        ``minimum`` nearest free points do, with any others as near as the last of them.
    taken : (n,) bool array_like, optional
        Points already owned by other handles: never selected (the deformer takes each point as
        a handle once).
    minimum : int
    pieces : (n,) array_like of int, optional
        Which piece of the shape each point is on (:meth:`solver.Graph.components`): the region
        stays on one piece, so a handle on a puppet's arm lying over its body takes none of the
        body's points. Without it, any point near enough.
    piece : int, optional
        The piece (a value of ``pieces``) the handle is on, where the caller knows it (the
        island of a selected vertex, the triangle a location falls on): where pieces overlap,
        points of several lie at ``centre``. By default the piece of the point nearest
        ``centre`` (the lowest index among points as near).

    Returns
    -------
    (k,) int64 ndarray
        Sorted by distance from ``centre``, nearest first.

    Raises
    ------
    ValueError
        Every point (of the piece, with ``pieces``) is taken.
    """
    points = np.asarray(points, dtype=np.float64)
    distance = np.linalg.norm(points - np.asarray(centre, dtype=np.float64), axis=1)
    if pieces is not None:
        pieces = np.asarray(pieces)
        piece = pieces[np.argmin(distance)] if piece is None else piece
        distance = np.where(pieces == piece, distance, np.inf)
    if taken is not None:
        distance = np.where(np.asarray(taken, dtype=bool), np.inf, distance)
    order = np.argsort(distance, kind="stable")
    free = int(np.isfinite(distance).sum())
    if free == 0:
        whole = taken is None or bool(np.all(taken))  # else only the piece there is full
        raise ValueError(f"every point of {'the shape' if whole else 'this piece of the shape'} already belongs "
                         "to a handle")
    inside = int((distance < radius).sum())
    count = min(max(inside, minimum), free)
    if count > inside:
        # Points as near as the last one taken come too: on a regular grid a vertex's
        # neighbours tie, and rounding (float32 data) would pick some of them by the shape's
        # size or place, and the pose with them.
        last = distance[order[count - 1]]
        count = int((distance <= last * (1.0 + TIE)).sum())
    return order[:count]


def region_offsets(frame, positions):
    """Region points in a handle's own coordinates, so the handle's frame carries them.

    Parameters
    ----------
    frame : (3, 3) array_like
        The handle's frame when the region was taken.
    positions : (k, 2) array_like
        The region points' positions at that moment.

    Returns
    -------
    (k, 2) float64 ndarray
    """
    return apply_affine(invert_affine(frame), positions)


def region_targets(frames, offsets, owners):
    """Deformer targets of all region points.

    Parameters
    ----------
    frames : (h, 3, 3) array_like
        Each handle's current frame.
    offsets : (m, 2) array_like
        Every region point's offset (see :func:`region_offsets`), handle after handle.
    owners : (m,) array_like of int
        The handle each offset belongs to.

    Returns
    -------
    (m, 2) float64 ndarray
    """
    frames = np.asarray(frames, dtype=np.float64).reshape(-1, 3, 3)
    return apply_affine(frames[np.asarray(owners, dtype=np.int64)], offsets)


def rest_position(rest_points, posed_points, triangles, query):
    """Where posed points came from: the rest positions of points given on the posed shape.

    Each query point is located in the posed triangulation (the nearest triangle if it lies
    outside) and carried back by its barycentric weights.

    Parameters
    ----------
    rest_points, posed_points : (n, 2) array_like
        Graph points at rest and posed.
    triangles : (t, 3) array_like of int
    query : (q, 2) array_like

    Returns
    -------
    (q, 2) float64 ndarray
    """
    posed = SimpleNamespace(points=np.asarray(posed_points, dtype=np.float64),
                            triangles=np.asarray(triangles, dtype=np.int64), n=len(posed_points))
    return bind(posed, np.asarray(query, dtype=np.float64).reshape(-1, 2)).apply(rest_points)


def distance_off(points, triangles, point):
    """How far ``point`` (2,) lies from the shape that ``triangles`` (t, 3) of ``points``
    (n, 2) cover: 0 inside it (on a face, however large), else the distance to its nearest edge."""
    points = np.asarray(points, dtype=np.float64)
    point = np.asarray(point, dtype=np.float64)
    corners = points[np.asarray(triangles)]                          # (t, 3, 2)
    starts, ends = corners, np.roll(corners, -1, axis=1)             # each triangle's edges
    edge, to_point = ends - starts, point - starts
    side = edge[..., 0] * to_point[..., 1] - edge[..., 1] * to_point[..., 0]
    if np.any(np.all(side >= 0.0, axis=1) | np.all(side <= 0.0, axis=1)):  # either winding
        return 0.0
    length = np.maximum(np.einsum("tkc,tkc->tk", edge, edge), np.finfo(np.float64).tiny)
    along = np.clip(np.einsum("tkc,tkc->tk", edge, to_point) / length, 0.0, 1.0)
    return float(np.min(np.linalg.norm(starts + along[..., None] * edge - point, axis=-1)))


# How far outside a triangle (in barycentric weight) a point still counts as on it: float32
# rounding of places up to a thousand triangle sizes from the origin stays under it.
ON_EDGE = 1e-4


def _layer_at(posed_points, posed_heights, triangles, point, height, rank=None):
    """Where the posed shape lies under ``point`` (2,) in the layer nearest ``height`` (the one
    in front where ``height`` is under them all; of layers level with one another, the one
    whose points have the highest ``rank`` (n,), else the last triangle's): the containing
    triangle's index and its barycentric weights (3,), or None where no triangle contains it.
    Where the pose folds the shape over itself several do, one per layer."""
    corners = np.asarray(posed_points, dtype=np.float64)[triangles]          # (t, 3, 2)
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    e1, e2, d = b - a, c - a, point - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    safe = np.where(np.abs(det) > 0.0, det, 1.0)
    w1 = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / safe
    w2 = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / safe
    weights = np.stack([1.0 - w1 - w2, w1, w2], axis=1)
    # On an edge by a hair: a point of one layer's outline, read back from float32 places, is
    # off its own triangles by rounding while it lies well inside the layer under it.
    inside = np.flatnonzero((np.abs(det) > 0.0) & np.all(weights >= -ON_EDGE, axis=1))
    if not len(inside):
        return None
    layer_heights = np.einsum("tk,tk->t", weights[inside], np.asarray(posed_heights, dtype=np.float64)[triangles[inside]])
    # Float32 places and the modifier's own interpolation are off the layers by a hair.
    hair = 1e-5 * float(np.ptp(np.asarray(posed_points, dtype=np.float64), axis=0).max(initial=0.0))
    # Under every layer (on the plane, as handles are): the one in front.
    target = layer_heights.max() if height < layer_heights.min() - hair else height
    gap = np.abs(layer_heights - target)
    # Layers level with one another (parts that overlap at rest): a drawing's layer drawn on top.
    level = inside[gap <= gap.min() + hair]
    best = level[-1] if rank is None else level[np.argmax(np.asarray(rank)[triangles[level, 0]])]
    return best, weights[best]


def place(plane, space, location, rest_points, posed_points, triangles, on_rest=False, posed_heights=None,
          snap=False, rank=None):
    """Where a handle added at ``location`` goes, in the shape's plane.

    Parameters
    ----------
    plane : solver.rigging.plane.Plane
        The shape's plane, in the rig's space.
    space : (4, 4) array_like
        The rig's space in the frame of ``location`` (in Blender, world space).
    location : (3,) array_like
    rest_points, posed_points : (n, 2) array_like
        Graph points at rest and as posed now.
    triangles : (t, 3) array_like of int
    on_rest : bool
        ``location`` is a point of the rest shape (a selected vertex), not of the posed one.
    posed_heights : (n,) array_like, optional
        Graph points' heights off the plane as posed (the depth that orders a fold's layers):
        where the pose folds the shape over itself, the handle goes on the layer whose height
        is nearest ``location``'s (the one clicked on; the one in front for a location under
        them all, on the plane), not on whichever the triangulation gives first.
    snap : bool
        Off the shape (with ``posed_heights``), go on its nearest posed point rather than
        where ``location`` is.
    rank : (n,) array_like, optional
        Where layers lie level (parts that overlap at rest), the one whose points rank highest
        (a drawing's layer drawn on top); without it, the last triangle's.

    Returns
    -------
    point : (2,) float64 ndarray
        The handle's place on the posed shape.
    rest_centre : (2,) float64 ndarray
        The rest point under it, around which its region is chosen.
    triangle : int or None
        The triangle it lies on, in the layer chosen (with ``posed_heights``): its piece is the
        one the handle is on, where pieces overlap. None where that is not known (on the rest
        shape, off the shape, or without heights).

    Raises
    ------
    ValueError
        ``space`` flattens the plane (an object scaled to zero across its shape), or
        ``location`` is not a finite point.
    """
    space = np.asarray(space, dtype=np.float64)
    if np.linalg.matrix_rank(space[:3, :3] @ plane.axes[:2].T) < 2:
        raise ValueError("scaled to zero across its shape: a handle cannot be placed on it")
    location = np.asarray(location, dtype=np.float64).reshape(3)
    # Blender stores a location as float32, clamping an infinity to float32's largest value.
    if not np.all(np.abs(location) < np.finfo(np.float32).max):
        raise ValueError("the handle's location is not a finite point")
    in_rig = transform_points(affine_inverse(space), location[None])
    point = plane.to_2d(in_rig)[0]
    if not np.all(np.isfinite(point)):
        raise ValueError("the handle's location is not a finite point")
    if on_rest:  # placed where that rest point is now, so it holds the shape as it is
        return rest_position(posed_points, rest_points, triangles, point[None])[0], point, None
    triangles = np.asarray(triangles, dtype=np.int64)
    layer = None if posed_heights is None else \
        _layer_at(posed_points, posed_heights, triangles, point, plane.heights(in_rig)[0], rank)
    if layer is None and snap and posed_heights is not None:  # without heights no layer is looked for
        posed_points = np.asarray(posed_points, dtype=np.float64)
        nearest = int(np.argmin(np.linalg.norm(posed_points - point, axis=1)))
        return posed_points[nearest], np.asarray(rest_points, dtype=np.float64)[nearest], None
    if layer is None:
        return point, rest_position(rest_points, posed_points, triangles, point[None])[0], None
    triangle, weights = layer
    return point, weights @ np.asarray(rest_points, dtype=np.float64)[triangles[triangle]], int(triangle)
