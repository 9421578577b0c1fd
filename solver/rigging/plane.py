"""The plane a flat 3D shape lies in, and coordinates in it.

Blender shapes that are 2D still live in 3D: a mesh modelled in the top view lies in XY, Blender's
own grease-pencil objects are drawn in XZ, an imported picture may stand at any angle. The rig
works in 2D coordinates of the shape's own plane, found from its points by principal component
analysis (the plane through the centroid whose normal is the direction of least spread).

The in-plane axes are chosen so that a shape drawn in a standard view comes out the right way
up: XY (top view) gives u = X, v = Y; XZ (front view) gives u = X, v = Z; YZ (side view) gives
u = Y, v = Z. The frame ``(u, v, normal)`` is right-handed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .depth import HEIGHT_PER_SCORE

__all__ = ["Plane", "fit_plane", "transform_points", "affine_inverse", "DEFAULT_FLATNESS"]

# A shape is flat when no point is further than this fraction of its size from the plane: as
# far as the rig's automatic depth lifts a pose (below ``depth.HEIGHT_PER_SCORE`` of the size),
# so a pose applied (its modifier applied, or the object converted) can be bound again; it
# was refused at 1e-4, which only float32 rounding (about 1e-7 of the size) stays below.
DEFAULT_FLATNESS = HEIGHT_PER_SCORE

# Sign of the normal: dotted with this it must be positive, which picks +Z for the top view,
# -Y for the front view (X to the right, Z up) and +X for the side view.
_NORMAL_PREFERENCE = np.array([1.0, -1.0, 1.0]) * np.array([1.0, 1.0 + 1e-3, 1.0 + 2e-3])


@dataclass(frozen=True)
class Plane:
    """An oriented plane with 2D coordinates.

    Attributes
    ----------
    origin : (3,) float64 ndarray
        The point with 2D coordinates (0, 0).
    axes : (3, 3) float64 ndarray
        Rows ``u``, ``v`` and ``normal``: orthonormal and right-handed.
    """

    origin: np.ndarray
    axes: np.ndarray

    @property
    def normal(self):
        """The plane's unit normal, (3,)."""
        return self.axes[2]

    def to_2d(self, points):
        """Coordinates of 3D ``points`` (p, 3) in the plane, shape (p, 2) (dropping height)."""
        return (np.asarray(points, dtype=np.float64) - self.origin) @ self.axes[:2].T

    def heights(self, points):
        """Signed distance of 3D ``points`` (p, 3) from the plane along its normal, shape (p,)."""
        return (np.asarray(points, dtype=np.float64) - self.origin) @ self.axes[2]

    def to_3d(self, points, heights=None):
        """3D points (p, 3) at 2D ``points`` (p, 2), lifted by ``heights`` (p,) if given.

        Passing the rest heights keeps points that were slightly off the plane exactly as far
        off, so a flat shape stays flat and a rest pose maps back to its rest points.
        """
        result = self.origin + np.asarray(points, dtype=np.float64) @ self.axes[:2]
        if heights is not None:
            result += np.asarray(heights, dtype=np.float64)[:, None] * self.axes[2]
        return result

    def to_array(self):
        """The plane as 12 numbers (origin, u, v, normal), for storing."""
        return np.concatenate([self.origin, self.axes.ravel()])

    @classmethod
    def from_array(cls, values):
        """Inverse of :meth:`to_array`."""
        values = np.asarray(values, dtype=np.float64).ravel()
        if values.shape != (12,):
            raise ValueError(f"a stored plane has 12 numbers, got {values.shape[0]}")
        return cls(values[:3].copy(), values[3:].reshape(3, 3).copy())


def fit_plane(points, flatness=DEFAULT_FLATNESS, line_normal=None):
    """The best-fit plane of 3D points, refusing points that are not flat.

    Parameters
    ----------
    points : (p, 3) array_like
    flatness : float
        Largest distance from the plane allowed, as a fraction of the points' size (the
        diagonal of their bounding box).
    line_normal : (3,) array_like, optional
        For points on one line, which lie in many planes (a straight stroke, which its width
        gives an area): the plane containing the line whose normal is nearest this one (the
        object's drawing plane). Without it such points are refused.

    Returns
    -------
    Plane

    Raises
    ------
    ValueError
        No points, non-finite points, points at one place, points on a line (without
        ``line_normal``), or points further from their plane than allowed; the message says
        how far.
    """
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must be a (p, 3) array, got shape {points.shape}")
    if len(points) == 0:
        raise ValueError("there are no points")
    if not np.all(np.isfinite(points)):
        raise ValueError("some points have non-finite coordinates (NaN or inf)")
    size = float(np.linalg.norm(np.ptp(points, axis=0)))
    if size == 0.0:
        raise ValueError("it has no area: all its points are at one place")
    origin = points.mean(axis=0)
    _, spread, directions = np.linalg.svd(points - origin, full_matrices=False)
    if len(points) < 3 or spread[1] <= 1e-9 * spread[0]:
        if line_normal is None:
            raise ValueError("it has no area: all its points lie on one line")
        normal = _across(directions[0], np.asarray(line_normal, dtype=np.float64))
    else:
        normal = directions[2]
    if normal @ _NORMAL_PREFERENCE < 0:
        normal = -normal
    deviation = float(np.abs((points - origin) @ normal).max())
    if deviation > flatness * size:
        raise ValueError(f"it is not planar: its points are up to {deviation:.4g} off their best-fit plane "
                         f"({deviation / size:.2%} of its size; at most {flatness:.2%} is allowed)")
    # u: the world X axis (Y if X is nearly along the normal) laid into the plane.
    world = np.eye(3)
    axis = world[0] if abs(normal[0]) < 0.9 else world[1]
    u = axis - (axis @ normal) * normal
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    return Plane(origin, np.stack([u, v, normal]))


def _across(line, preferred):
    """The unit normal of a plane containing direction ``line`` that is nearest ``preferred``
    (or, where that runs along the line, nearest a world axis across it)."""
    for candidate in (preferred, *np.eye(3)[np.argsort(np.abs(line))]):
        normal = candidate - (candidate @ line) * line
        length = float(np.linalg.norm(normal))
        if length > 1e-6 * float(np.linalg.norm(candidate)):
            return normal / length
    raise ValueError("no plane found across the line")  # unreachable: some world axis is across it


def transform_points(matrix, points):
    """Apply a 4x4 affine ``matrix`` to 3D ``points`` (p, 3); returns (p, 3) float64."""
    matrix = np.asarray(matrix, dtype=np.float64)
    return np.asarray(points, dtype=np.float64).reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]


def affine_inverse(matrix):
    """The inverse of a 4x4 affine ``matrix``; where it is singular (an object scaled to zero
    along an axis) the least-squares inverse of its linear part, so points keep their
    coordinates along the axes it does not flatten. Returns (4, 4) float64."""
    matrix = np.asarray(matrix, dtype=np.float64)
    try:
        return np.linalg.inv(matrix)
    except np.linalg.LinAlgError:
        linear = np.linalg.pinv(matrix[:3, :3])
        inverse = np.eye(4)
        inverse[:3, :3] = linear
        inverse[:3, 3] = -linear @ matrix[:3, 3]
        return inverse
