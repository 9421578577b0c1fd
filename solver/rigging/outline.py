"""Outlines of Blender-style geometry: boundary loops of triangle meshes, sampled Bezier splines,
how well shaped a mesh's own triangles are, and how finely a fill must be cut to bend.

The graph built from such an outline with a chosen number of points is
:func:`solver.outline.outline_graph`.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..shapes import clean_ring

# Faces a refined fill may have: about the points of the 50,000-vertex mesh whose evaluation
# docs/addon_speed.md times at 2.7 ms (benchmarks/addon_speed.py), so a text keeps playing live.
REFINE_BUDGET = 50_000

__all__ = ["boundary_loops", "sample_bezier", "sample_nurbs", "smallest_angles", "with_area", "wound_alike",
           "refine_level"]


def boundary_loops(triangles):
    """Closed loops of the edges used by exactly one triangle.

    Parameters
    ----------
    triangles : (t, 3) array_like of int
        In any winding: a face wound against its neighbours (a normal flipped in Blender) is
        turned to match them first.

    Returns
    -------
    list of (k,) int64 ndarray
        Vertex indices of each loop in order (orientation not fixed).

    Raises
    ------
    ValueError
        No triangles, or a boundary that does not split into simple loops (a vertex where
        several boundary pieces meet: a non-manifold mesh).
    """
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(triangles) == 0:
        raise ValueError("it has no faces")
    directed, edge, counts = _edge_uses(wound_alike(triangles))
    boundary = directed[counts[edge] == 1]
    if len(boundary) == 0:
        raise ValueError("it has no boundary (a closed surface is not a flat shape)")
    starts, ends = boundary[:, 0], boundary[:, 1]
    if len(np.unique(starts)) != len(starts) or len(np.unique(ends)) != len(ends):
        raise ValueError("its boundary is not manifold: several boundary edges meet at one vertex")
    following = dict(zip(starts.tolist(), ends.tolist()))
    loops = []
    # Walking a loop is sequential by nature; it runs once at bind time over boundary vertices.
    while following:
        first, current = next(iter(following.items()))
        loop = [first]
        del following[first]
        while current != first:
            loop.append(current)
            nxt = following.pop(current, None)
            if nxt is None:
                raise ValueError("its boundary edges do not form closed loops")
            current = nxt
        loops.append(np.array(loop, dtype=np.int64))
    return loops


def wound_alike(triangles):
    """The triangles with every piece wound one way, as Blender's Recalculate Normals does.

    Two triangles sharing an edge are wound alike when they run it in opposite directions. The
    winding is fixed by the mesh's connections alone, not by the plane, so a face that is flat
    in the plane (its corners on one line) or lies folded over its neighbours follows them too.

    Parameters
    ----------
    triangles : (t, 3) array_like of int

    Returns
    -------
    (t, 3) int64 ndarray
        The same triangles, some with two corners swapped. Pieces joined only through an edge
        of three or more triangles, or at a corner, are wound independently; a piece that
        cannot be wound one way (a Moebius strip) is left as it is.
    """
    triangles = np.array(triangles, dtype=np.int64).reshape(-1, 3)
    t = len(triangles)
    directed, edge, counts = _edge_uses(triangles)
    shared = np.flatnonzero(counts[edge] == 2)
    uses = shared[np.argsort(edge[shared], kind="stable")].reshape(-1, 2)  # an edge's two uses
    first, second = uses[:, 0] % t, uses[:, 1] % t  # the triangle of each use
    alike = directed[uses[:, 0], 0] != directed[uses[:, 1], 0]
    # Node f is triangle f as wound, node f + t the same triangle turned over; a shared edge joins
    # the two nodes that agree. Each piece splits into two components, one per consistent
    # winding: keep, for every triangle, the winding in the component with the lower label.
    partner = np.where(alike, second, second + t)
    rows = np.concatenate([first, first + t])
    cols = np.concatenate([partner, (partner + t) % (2 * t)])
    cover = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(2 * t, 2 * t))
    label = connected_components(cover, directed=False)[1]
    turn = label[:t] > label[t:]
    triangles[turn] = triangles[turn][:, ::-1]
    return triangles


def _edge_uses(triangles):
    """Each triangle's edges as it runs them, (3 t, 2) (the t first edges, then the t second
    ones, then the third), which undirected edge each is (3 t,), and how many triangles use
    each undirected edge (e,)."""
    directed = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    _, edge, counts = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True)
    return directed, edge.ravel(), counts


def sample_bezier(points, left, right, cyclic, resolution=12):
    """Points along a cubic Bezier spline, as Blender draws it.

    Parameters
    ----------
    points, left, right : (k, d) array_like
        Control points and their left and right handles.
    cyclic : bool
        Whether the last segment joins the last point to the first.
    resolution : int
        Samples per segment (Blender's ``resolution_u``).

    Returns
    -------
    (m, d) float64 ndarray
        Each segment's samples from its start (excluded end); an open spline also gets its last
        point.
    """
    p0 = np.asarray(points, dtype=np.float64)
    left = np.asarray(left, dtype=np.float64)
    right = np.asarray(right, dtype=np.float64)
    resolution = max(int(resolution), 1)
    nxt = np.roll(np.arange(len(p0)), -1)
    if not cyclic:
        nxt = nxt[:-1]
    start = np.arange(len(nxt))
    a, b, c, d = p0[start], right[start], left[nxt], p0[nxt]
    t = (np.arange(resolution) / resolution)[None, :, None]
    s = 1.0 - t
    curve = (s ** 3 * a[:, None] + 3 * s * s * t * b[:, None] + 3 * s * t * t * c[:, None]
             + t ** 3 * d[:, None]).reshape(-1, p0.shape[1])
    if not cyclic:
        curve = np.concatenate([curve, p0[-1:]])
    return curve


def sample_nurbs(points, weights, order, cyclic, endpoint=False, bezier=False, resolution=12, per_span=True):
    """Points along a NURBS spline, as Blender draws it.

    Blender's knots are whole numbers: the first ones repeated for Endpoint (the curve starts
    and ends at its end points), the inner ones ``order - 1`` times for Bezier (the curve passes
    through every ``order - 1``-th point). A spline Blender cannot draw (fewer points than its
    order, or a Bezier count that does not fit the order) is drawn through its points, and so is
    it returned.

    Parameters
    ----------
    points : (k, d) array_like
        Control points.
    weights : (k,) array_like
        Their weights (the fourth component of Blender's ``SplinePoint.co``).
    order : int
        Blender's ``order_u``: the degree plus one.
    cyclic, endpoint, bezier : bool
        ``use_cyclic_u``, ``use_endpoint_u`` and ``use_bezier_u``.
    resolution : int
        ``resolution_u``.
    per_span : bool
        How Blender spaces the samples: since 5.0 ``resolution`` in each span of nonzero
        length; before, ``resolution`` per gap between points, evenly over the whole curve.

    Returns
    -------
    (m, d) float64 ndarray
        The samples in order; an open spline's last one is its end.
    """
    points = np.asarray(points, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    k, order, resolution = len(points), int(order), max(int(resolution), 1)
    if not _drawable_nurbs(k, order, cyclic, bezier, endpoint):
        return points.copy()
    knots = _nurbs_knots(k, order, cyclic, endpoint, bezier)
    spans = k + (order - 1 if cyclic else 0)   # basis functions: a cyclic spline wraps its first points
    if per_span:
        starts, ends = knots[order - 1:spans], knots[order:spans + 1]
        steps = np.arange(resolution) / resolution
        t = (starts[ends > starts, None] + (ends - starts)[ends > starts, None] * steps).ravel()
        if not cyclic:
            t = np.append(t, knots[spans])
    else:
        count = resolution * (k if cyclic else k - 1)
        t = np.linspace(knots[order - 1], knots[spans], count, endpoint=not cyclic)
    basis = _bspline_basis(knots, order, t)[:, :spans]
    # A cyclic spline's extra basis functions belong to its first points.
    folded = np.zeros((len(t), k))
    np.add.at(folded.T, np.arange(spans) % k, basis.T)
    rational = folded * weights
    return (rational @ points) / rational.sum(axis=1, keepdims=True)


def _drawable_nurbs(count, order, cyclic, bezier, endpoint):
    """Whether Blender draws a NURBS spline as a curve (else through its points)."""
    if count < order or order < 2:
        return False
    if bezier:
        if not endpoint and count <= order:
            return False
        return not cyclic or count % (order - 1) == 0
    return True


def _nurbs_knots(count, order, cyclic, endpoint, bezier):
    """Blender's knot vector of a NURBS spline, (count + order (+ order - 1 when cyclic),)."""
    total = count + order + (order - 1 if cyclic else 0)
    repeat = order - 1 if bezier else 1
    head = order - int(cyclic) if endpoint else (min(2, repeat) if bezier else 1)
    tail = 2 * order - 1 if cyclic else (order if endpoint else 0)
    first = int(endpoint and cyclic)   # cyclic with Endpoint: a lone knot 0 before the first run
    body = total - tail - first
    # The body counts up from `first` in runs: the first `head` long, the others `repeat`.
    runs = np.where(np.arange(body) < head, 0, 1 + (np.arange(body) - head) // repeat)
    knots = np.concatenate([np.zeros(first), first + runs])
    run_complete = body >= head and (body - head) % repeat == 0
    following = knots[-1] + 1 if run_complete else knots[-1]
    # The tail repeats the widths of the first knots past the body; a tail longer than the body
    # goes on repeating its own first knots.
    knots = np.concatenate([knots, np.zeros(tail)])
    for i in range(tail):
        knots[body + first + i] = following + knots[i] - knots[0]
    return knots


def _bspline_basis(knots, order, t):
    """Values of every B-spline basis function at parameters ``t``, (len(t), len(knots) - order).

    Cox and de Boor's recursion, starting from the first span of nonzero length that holds each
    parameter (its closed interval, so an open spline's last parameter is in its last span).
    """
    nonzero = knots[1:] > knots[:-1]
    inside = (knots[:-1] <= t[:, None]) & (t[:, None] <= knots[1:]) & nonzero
    values = np.zeros((len(t), len(knots) - 1))
    values[np.arange(len(t)), inside.argmax(axis=1)] = 1.0
    for degree in range(1, order):
        width_up = knots[degree:-1] - knots[:-degree - 1]
        width_down = knots[degree + 1:] - knots[1:-degree]
        rising = np.divide(t[:, None] - knots[:-degree - 1], width_up, out=np.zeros((len(t), len(width_up))),
                           where=width_up > 0)
        falling = np.divide(knots[degree + 1:] - t[:, None], width_down, out=np.zeros_like(rising),
                            where=width_down > 0)
        values = rising * values[:, :-1] + falling * values[:, 1:]
    return values


def smallest_angles(points, triangles):
    """Smallest interior angle of each triangle, in radians: how far from a sliver it is.

    Parameters
    ----------
    points : (n, 2) array_like
    triangles : (t, 3) array_like of int

    Returns
    -------
    (t,) float64 ndarray
        0 for a degenerate triangle.
    """
    points = np.asarray(points, dtype=np.float64)
    corners = points[np.asarray(triangles, dtype=np.int64).reshape(-1, 3)]
    sides = np.roll(corners, -1, axis=1) - corners          # edge k runs from corner k to k + 1
    lengths = np.linalg.norm(sides, axis=2)
    a, b = -np.roll(sides, 1, axis=1), sides                 # the two edges leaving each corner
    cosine = np.einsum("tki,tki->tk", a, b) / np.maximum(np.roll(lengths, 1, axis=1) * lengths, 1e-300)
    angles = np.arccos(np.clip(cosine, -1.0, 1.0))
    angles[(lengths == 0).any(axis=1)] = 0.0
    return angles.min(axis=1)


def with_area(rings):
    """The rings that bound some area, in order: a closed spline or a face's loop whose points
    all lie on one line (or at fewer than three places) draws nothing filled, and is left out
    rather than refusing the whole shape.

    Parameters
    ----------
    rings : list of (k, 2) array_like

    Returns
    -------
    list of (k, 2) array_like
    """
    kept = []
    for ring in rings:
        try:
            clean_ring(ring)
        except ValueError:
            continue
        kept.append(ring)
    return kept


def refine_level(points, edges, face_count, spacing, most, budget=REFINE_BUDGET):
    """How many times to subdivide a fill (a text's or filled curve's faces, which span the
    shape from outline to outline) before it is mapped through the cage.

    The cage's map is linear within each of its triangles, so a face bends only where it has
    vertices: each level halves the fill's edges, until the longest is no longer than the
    graph's spacing, and makes four faces of each, up to ``budget`` faces in all.

    Parameters
    ----------
    points : (n, 2) array_like
        The fill's vertices, in the graph's plane.
    edges : (k, 2) array_like of int
    face_count : int
        Faces of the fill.
    spacing : float
        The graph's spacing (:attr:`solver.Graph.spacing`).
    most : int
        The highest level the deformer offers.
    budget : int
        The most faces the refined fill may have.

    Returns
    -------
    int
        0 for a fill with no faces or no edge longer than the spacing.
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if face_count == 0 or len(edges) == 0:
        return 0
    points = np.asarray(points, dtype=np.float64)
    longest = float(np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1).max())
    needed = np.ceil(np.log2(max(longest / spacing, 1.0)))
    affordable = np.floor(np.log(max(budget / face_count, 1.0)) / np.log(4.0))
    return int(min(needed, affordable, most))
