"""Quality measures of a deformed triangulated 2D shape, the same for every method compared.

Every function takes the rest positions, the deformed positions and the shape's triangles (or
boundary loops), never anything method-specific, so a peer's output is measured exactly like ours.
Plain numpy: no solver internals, no bpy, no matplotlib.

Definitions (used verbatim in docs/benchmarks.md):

* handle error: largest distance between a handle and its target, as a fraction of the largest
  handle displacement (the size of the drag);
* area ratio: deformed area / rest area, summed over triangles with their signs;
* local area spread: for each unflipped triangle ``log(a / a0)``; the 5-95 percentile range;
* ARAP energy per area: ``sum_t a0_t ||J_t - R_t||_F^2 / sum_t a0_t`` with ``J_t`` the
  triangle's deformation gradient and ``R_t`` the rotation closest to it (zero for any rigid
  motion, 2 for a triangle scaled to a point);
* boundary Laplacian change: for each boundary vertex ``delta = v_i - (v_{i-1} + v_{i+1}) / 2``
  now and at rest; the rest one is turned by the rotation that best maps the vertex's two rest
  curve edges onto its current ones (2D Procrustes); the mean of ``|delta - R delta0|`` over all
  boundary vertices, divided by the mean rest boundary edge length;
* flips: triangles whose signed area is <= 0 after the deformation.
"""

from __future__ import annotations

import numpy as np

__all__ = ["triangle_areas", "deformation_gradients", "arap_energy_per_area", "area_ratio",
           "local_area_spread", "flipped", "handle_error", "boundary_laplacian_change", "measure"]


def triangle_areas(positions, triangles):
    """Signed area of each triangle, shape (t,)."""
    p = np.asarray(positions, dtype=np.float64)[:, :2]
    a, b, c = (p[triangles[:, k]] for k in range(3))
    u, v = b - a, c - a
    return 0.5 * (u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


def _edge_frames(positions, triangles):
    """(t, 2, 2) matrices whose columns are the edges b - a and c - a of each triangle."""
    p = np.asarray(positions, dtype=np.float64)[:, :2]
    a, b, c = (p[triangles[:, k]] for k in range(3))
    return np.stack([b - a, c - a], axis=2)


def deformation_gradients(rest, deformed, triangles):
    """The 2x2 linear map J_t taking each rest triangle's edges onto its deformed edges, (t, 2, 2)."""
    return _edge_frames(deformed, triangles) @ np.linalg.inv(_edge_frames(rest, triangles))


def _distance_to_rotations(gradients):
    """``min_R ||J - R||_F^2`` over proper rotations, per gradient (closed form in 2D).

    ``||J - R(theta)||^2 = ||J||^2 + 2 - 2 ((a + d) cos theta + (c - b) sin theta)``, smallest at
    the angle of ``(a + d, c - b)``, where the bracket is the length of that vector.
    """
    a, b = gradients[:, 0, 0], gradients[:, 0, 1]
    c, d = gradients[:, 1, 0], gradients[:, 1, 1]
    frobenius = a * a + b * b + c * c + d * d
    return np.maximum(frobenius + 2.0 - 2.0 * np.hypot(a + d, c - b), 0.0)


def arap_energy_per_area(rest, deformed, triangles):
    """Rest-area weighted mean of ``||J - R||_F^2`` (0 for a rigid motion)."""
    weights = np.abs(triangle_areas(rest, triangles))
    energy = _distance_to_rotations(deformation_gradients(rest, deformed, triangles))
    return float(np.dot(weights, energy) / weights.sum())


def area_ratio(rest, deformed, triangles):
    """Deformed total signed area / rest total signed area."""
    return float(triangle_areas(deformed, triangles).sum() / triangle_areas(rest, triangles).sum())


def local_area_spread(rest, deformed, triangles, low=5.0, high=95.0):
    """The ``low``-``high`` percentile range of ``log(a / a0)`` over unflipped triangles."""
    ratio = triangle_areas(deformed, triangles) / triangle_areas(rest, triangles)
    ratio = ratio[ratio > 0]
    if len(ratio) == 0:
        return float("nan")
    low_value, high_value = np.percentile(np.log(ratio), [low, high])
    return float(high_value - low_value)


def flipped(rest, deformed, triangles):
    """Number of triangles whose orientation flipped or collapsed."""
    rest_sign = np.sign(triangle_areas(rest, triangles))
    return int(np.count_nonzero(triangle_areas(deformed, triangles) * rest_sign <= 0))


def handle_error(rest, deformed, handles, targets):
    """Largest handle-to-target distance over the largest handle displacement."""
    deformed = np.asarray(deformed, dtype=np.float64)[:, :2]
    targets = np.asarray(targets, dtype=np.float64)
    miss = np.linalg.norm(deformed[handles] - targets, axis=1).max()
    drag = np.linalg.norm(np.asarray(rest)[handles, :2] - targets, axis=1).max()
    return float(miss / drag) if drag > 0 else float(miss)


def boundary_laplacian_change(rest, deformed, loops):
    """Mean ``|delta_i - R_i delta0_i|`` over boundary vertices / mean rest boundary edge."""
    rest = np.asarray(rest, dtype=np.float64)[:, :2]
    deformed = np.asarray(deformed, dtype=np.float64)[:, :2]
    changes, edges = [], []
    for loop in loops:
        loop = np.asarray(loop)
        before, after = np.roll(loop, 1), np.roll(loop, -1)
        delta0 = rest[loop] - 0.5 * (rest[before] + rest[after])
        delta = deformed[loop] - 0.5 * (deformed[before] + deformed[after])
        # Rotation fitted to the two curve edges at each vertex (2D Procrustes).
        cos = np.zeros(len(loop))
        sin = np.zeros(len(loop))
        for neighbour in (before, after):
            e0 = rest[neighbour] - rest[loop]
            e = deformed[neighbour] - deformed[loop]
            cos += e0[:, 0] * e[:, 0] + e0[:, 1] * e[:, 1]
            sin += e0[:, 0] * e[:, 1] - e0[:, 1] * e[:, 0]
        norm = np.hypot(cos, sin)
        safe = np.where(norm > 0, norm, 1.0)
        cos, sin = np.where(norm > 0, cos / safe, 1.0), np.where(norm > 0, sin / safe, 0.0)
        turned = np.stack([cos * delta0[:, 0] - sin * delta0[:, 1],
                           sin * delta0[:, 0] + cos * delta0[:, 1]], axis=1)
        changes.append(np.linalg.norm(delta - turned, axis=1))
        edges.append(np.linalg.norm(rest[after] - rest[loop], axis=1))
    return float(np.concatenate(changes).mean() / np.concatenate(edges).mean())


def measure(rest, deformed, triangles, loops, handles, targets):
    """All the quality measures above as a dict (keys as in the tables)."""
    return {
        "handle error": handle_error(rest, deformed, handles, targets),
        "area ratio": area_ratio(rest, deformed, triangles),
        "local area spread": local_area_spread(rest, deformed, triangles),
        "ARAP / area": arap_energy_per_area(rest, deformed, triangles),
        "boundary Laplacian": boundary_laplacian_change(rest, deformed, loops),
        "flips": flipped(rest, deformed, triangles),
    }
