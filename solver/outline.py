"""The paper's graph for an outline given a number of points rather than a spacing: the spacing
that gives about that many points, and the outline simplified to it.
"""

from __future__ import annotations

from .shapes import shape_geometry

__all__ = ["spacing_for_count", "simplify_rings", "outline_graph"]


def spacing_for_count(rings, count):
    """Lattice spacing that puts about ``count`` points inside the shape bounded by ``rings``.

    Parameters
    ----------
    rings : sequence of (k, 2) array_like
    count : int

    Returns
    -------
    float
    """
    from .graph import spacing_for

    if count < 1:
        raise ValueError(f"count must be positive, got {count}")
    return spacing_for(shape_geometry(rings), count)


def simplify_rings(rings, tolerance):
    """Rings with points that add less than ``tolerance`` of detail removed (topology kept).

    A dense mesh's outline or a finely swept silhouette has far more boundary points than the
    graph needs; the graph's own boundary is then subdivided to its spacing again.

    Parameters
    ----------
    rings : sequence of (k, 2) array_like
    tolerance : float

    Returns
    -------
    list of (k', 2) float64 ndarray
    """
    import shapely

    from .shapes import geometry_rings, shape_geometry

    geometry = shape_geometry(rings)
    simplified = shapely.simplify(geometry, tolerance, preserve_topology=True)
    if simplified.is_empty or not simplified.is_valid:
        simplified = geometry
    return [ring for island in geometry_rings(simplified) for ring in island]


def outline_graph(rings, count, detail=0.02):
    """The paper's graph for ``rings`` with about ``count`` interior points and a boundary
    resampled to the same spacing (see :func:`simplify_rings`), keeping outline detail down to
    ``detail`` times that spacing."""
    from .graph import build_graph

    spacing = spacing_for_count(rings, count)
    return build_graph(simplify_rings(rings, detail * spacing), spacing)
