"""The paper's graph for an outline given a number of points rather than a spacing: the spacing
that gives about that many points, and the outline simplified to it.
"""

from __future__ import annotations

import numpy as np

from .shapes import shape_geometry, signed_area

__all__ = ["spacing_for_count", "simplify_rings", "outline_graph", "parts_graph"]


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


def simplify_rings(rings, tolerance, cover_within=None):
    """Rings with points that add less than ``tolerance`` of detail removed (topology kept),
    and holes and islands thinner than ``tolerance`` left out.

    A dense mesh's outline or a finely swept silhouette has far more boundary points than the
    graph needs; the graph's own boundary is then subdivided to its spacing again. A ring
    thinner than the detail kept (twice its area over its length: a needle's width, a disk's
    radius) is no detail of the shape, and the triangulation would refine round it without
    end (a closed spline whose points were on one line to float32 rounding, inside a circle,
    gave 55,000 points): it goes, unless it is all there is.

    With ``cover_within`` (rings of a region holding ``rings``: what a picture's plane shows of
    it) the result covers ``rings`` wholly instead: they are grown by ``tolerance`` first, so
    simplifying moves no point inside them, then clipped to the region, and no island is left
    out (a picture's cut-out is the mesh that shows it: at 4,096 pixels the spacing's detail of
    3 pixels had cut 1-pixel lines and dots off it, and the outline's pixels by up to 0.9).

    Parameters
    ----------
    rings : sequence of (k, 2) array_like
    tolerance : float
    cover_within : sequence of (k, 2) array_like, optional

    Returns
    -------
    list of (k', 2) float64 ndarray
    """
    import shapely

    from .shapes import geometry_rings, polygonal_part, shape_geometry

    geometry = shape_geometry(rings)
    if cover_within is not None:
        geometry = geometry.buffer(tolerance, join_style="mitre", mitre_limit=2.0)
    simplified = shapely.simplify(geometry, tolerance, preserve_topology=True)
    if simplified.is_empty or not simplified.is_valid:
        simplified = geometry
    if cover_within is not None:
        simplified = polygonal_part(shapely.intersection(simplified, shape_geometry(cover_within)))
    islands = geometry_rings(simplified)
    kept = [[island[0]] + [hole for hole in island[1:] if _width(hole) >= tolerance]
            for island in islands if cover_within is not None or _width(island[0]) >= tolerance]
    return [ring for island in (kept or islands) for ring in island]


def _width(ring):
    """Twice the area of a ring (k, 2) over its length."""
    length = float(np.linalg.norm(np.roll(ring, -1, axis=0) - ring, axis=1).sum())
    return 2.0 * abs(signed_area(ring)) / max(length, 1e-300)


def outline_graph(rings, count, detail=0.02, cover_within=None):
    """The paper's graph for ``rings`` with about ``count`` interior points and a boundary
    resampled to the same spacing (see :func:`simplify_rings`, which ``cover_within`` is passed
    to), keeping outline detail down to ``detail`` times that spacing."""
    from .graph import build_graph

    spacing = spacing_for_count(rings, count)
    return build_graph(simplify_rings(rings, detail * spacing, cover_within), spacing)


def parts_graph(parts, count, detail=0.02):
    """The paper's graph for shapes that may overlap and must stay apart (a puppet's arm drawn
    over its body): each part's graph as :func:`outline_graph` builds it, all at one spacing,
    joined as islands. No edge joins two parts, so each deforms alone (a part without handles
    stays at rest).

    Parameters
    ----------
    parts : sequence of sequences of (k, 2) array_like
        Each part's rings (outer boundaries, holes, islands of its own).
    count : int
        About how many interior points all parts have together.
    detail : float
        Outline detail kept, in units of the spacing.

    Returns
    -------
    graph : solver.Graph
    part : (n,) int64 ndarray
        Each point's part, an index into ``parts``.
    """
    import shapely

    from .graph import Graph, build_graph, spacing_for

    if count < 1:
        raise ValueError(f"count must be positive, got {count}")
    geometries = [shape_geometry(rings) for rings in parts]
    # A collection's area and length are its members' sums: overlaps count once per part.
    spacing = spacing_for(shapely.GeometryCollection(geometries), count)
    graphs = [build_graph(simplify_rings(rings, detail * spacing), spacing) for rings in parts]
    starts = np.cumsum([0] + [graph.n for graph in graphs[:-1]])
    joined = Graph(np.concatenate([graph.points for graph in graphs]),
                   np.concatenate([graph.edges + start for graph, start in zip(graphs, starts)]),
                   [loop + start for graph, start in zip(graphs, starts) for loop in graph.boundary_loops],
                   np.concatenate([graph.triangles + start for graph, start in zip(graphs, starts)]), spacing=spacing)
    return joined, np.repeat(np.arange(len(graphs)), [graph.n for graph in graphs])
