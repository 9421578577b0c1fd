"""Input shapes: validate rings, work out nesting and orientation, repair what can be repaired.

A shape arrives as closed rings, each a ``(k, 2)`` array, in any orientation and any order.
Rings nested at an even depth (0, 2, ...) bound material, rings at an odd depth bound holes.
Everything here returns oriented rings: outer boundaries counter-clockwise, holes clockwise,
so the signed areas of all rings add up to the shape's area.
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = ["box_centre", "signed_area", "clean_ring", "polygonal_part", "shape_geometry", "geometry_rings", "nesting_depth"]


def box_centre(points):
    """Centre of the bounding box of ``points`` (n, 2): the origin that computations far from
    the coordinate origin shift to, so their rounding scales with the shape, not its offset."""
    return 0.5 * (points.min(axis=0) + points.max(axis=0))


def signed_area(ring):
    """Signed area of a closed polygon (shoelace formula); positive when counter-clockwise.

    Parameters
    ----------
    ring : (k, 2) array_like
        Polygon vertices, without repeating the first one at the end.

    Returns
    -------
    float
    """
    ring = np.asarray(ring, dtype=np.float64)
    # The trapezoid form of the shoelace sum, on a centred ring: its terms scale with the edges
    # and the ring's size, not with its distance from the origin, so a ring far away or
    # stretched thin keeps its area (the plain form lost up to 5e-8 of it to cancellation).
    ring = ring - ring.mean(axis=0)
    x, y = ring[:, 0], ring[:, 1]
    following_x, following_y = np.roll(x, -1), np.roll(y, -1)
    return -0.5 * float(np.dot(following_x - x, following_y + y))


def clean_ring(ring, index=0):
    """Check one ring and drop repeated points.

    Parameters
    ----------
    ring : (k, 2) array_like
        Closed polygon; the closing point may or may not be repeated.
    index : int
        Position of the ring in the caller's list, used in error messages.

    Returns
    -------
    (k', 2) float64 ndarray
        The ring with consecutive duplicates (and a repeated closing point) removed.

    Raises
    ------
    ValueError
        Wrong shape, non-finite coordinates, fewer than 3 distinct points, or zero area.
    """
    try:
        points = np.asarray(ring, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"ring {index} is not an array of numbers: {err}") from None
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"ring {index} must be a (k, 2) array of points, got shape {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError(f"ring {index} has non-finite coordinates (NaN or inf)")
    if len(points) == 0:
        raise ValueError(f"ring {index} is empty")
    extent = float(np.ptp(points, axis=0).max())
    # Two points closer than this are the same point: rounding noise, not geometry.
    tolerance = 1e-12 * max(extent, float(np.abs(points).max()), 1e-300)
    step = np.linalg.norm(points - np.roll(points, 1, axis=0), axis=1)
    points = points[step > tolerance] if len(points) > 1 else points
    if len(np.unique(points, axis=0)) < 3:
        raise ValueError(f"ring {index} has fewer than 3 distinct points")
    # Collinear, not zero signed area: a figure eight's lobes cancel but it bounds area.
    thickness = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)[-1]
    if thickness <= 1e-12 * extent * np.sqrt(len(points)):
        raise ValueError(f"ring {index} has zero area (all its points are on one line)")
    return points


def polygonal_part(geometry):
    """Keep only the polygons of a geometry (make_valid may also return lines and points)."""
    parts = shapely.get_parts(geometry)
    polygons = [p for p in parts if isinstance(p, (shapely.Polygon, shapely.MultiPolygon))]
    if not polygons:
        return shapely.Polygon()
    return shapely.union_all(polygons)


def shape_geometry(rings):
    """Turn rings into one valid shapely geometry: islands with their holes.

    Nesting is worked out from containment, never from orientation: a ring inside an odd
    number of other rings is a hole. A ring repeated exactly counts once. Overlapping islands
    are merged. A self-intersecting ring is repaired (a figure eight becomes two lobes) when
    its repair keeps area.

    Parameters
    ----------
    rings : sequence of (k, 2) array_like

    Returns
    -------
    shapely.Polygon or shapely.MultiPolygon
        Valid, with counter-clockwise exteriors and clockwise holes.

    Raises
    ------
    ValueError
        No rings, a malformed ring (see :func:`clean_ring`), or a self-intersecting ring
        that has no area once repaired.
    """
    if isinstance(rings, np.ndarray) and rings.ndim == 2:
        rings = [rings]
    rings = list(rings) if rings is not None else []
    if not rings:
        raise ValueError("no rings: a shape needs at least one closed ring")
    cleaned = [clean_ring(ring, i) for i, ring in enumerate(rings)]

    polygons = []
    for i, ring in enumerate(cleaned):
        polygon = shapely.Polygon(ring)
        if not polygon.is_valid:
            polygon = polygonal_part(shapely.make_valid(polygon))
            if polygon.is_empty or polygon.area <= 1e-9 * abs(signed_area(ring)) + 1e-300:
                raise ValueError(f"ring {i} is self-intersecting and cannot be repaired")
        polygons.append(polygon)
    # A ring drawn twice on itself (a spline duplicated in place) is one outline: by nesting the
    # two would make each other a hole, and nothing would be left (QA).
    _, first = np.unique(shapely.to_wkb(shapely.normalize(polygons)), return_index=True)
    polygons = [polygons[i] for i in np.sort(first)]

    if len(polygons) == 1:
        geometry = polygons[0]
    else:
        depth = nesting_depth(polygons)
        islands = []
        for i in np.flatnonzero(depth % 2 == 0):
            holes = [polygons[j] for j in np.flatnonzero(depth == depth[i] + 1)
                     if polygons[i].contains(polygons[j])]
            island = polygons[i]
            if holes:
                island = shapely.difference(island, shapely.union_all(holes))
            islands.append(island)
        geometry = polygonal_part(shapely.union_all(islands))
    if geometry.is_empty or geometry.area <= 0.0:
        raise ValueError("the rings enclose no area")
    geometry = _separate_pinches(geometry)
    return shapely.orient_polygons(geometry, exterior_cw=False)


def _separate_pinches(geometry):
    """Pull apart rings that touch at a point (a repaired figure eight, a hole touching its
    outline): a vertex shared by two loops cannot be triangulated on both sides."""
    points = np.concatenate([ring for island in geometry_rings(geometry) for ring in island])
    if len(np.unique(points, axis=0)) == len(points):
        return geometry
    size = float(np.linalg.norm(np.ptp(points, axis=0)))
    separated = geometry.buffer(-1e-6 * size, join_style="mitre", mitre_limit=10.0)
    return polygonal_part(separated) if not separated.is_empty else geometry


def nesting_depth(polygons):
    """How many of the other polygons contain each polygon (even: material, odd: a hole).

    Parameters
    ----------
    polygons : sequence of shapely.Polygon

    Returns
    -------
    (k,) int64 ndarray
    """
    tree = shapely.STRtree(polygons)
    inner, outer = tree.query(polygons, predicate="within")
    keep = inner != outer
    return np.bincount(inner[keep], minlength=len(polygons))


def geometry_rings(geometry):
    """Oriented rings of a shapely (multi)polygon, island by island.

    Parameters
    ----------
    geometry : shapely.Polygon or shapely.MultiPolygon

    Returns
    -------
    list of list of (k, 2) float64 ndarray
        One list per island: its outer ring (counter-clockwise) first, then its holes
        (clockwise). Closing points are not repeated.
    """
    geometry = shapely.orient_polygons(geometry, exterior_cw=False)
    islands = []
    for polygon in shapely.get_parts(geometry):
        rings = [np.asarray(polygon.exterior.coords, dtype=np.float64)[:-1]]
        rings += [np.asarray(hole.coords, dtype=np.float64)[:-1] for hole in polygon.interiors]
        islands.append(rings)
    return islands
