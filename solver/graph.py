"""The interior graph of a 2D shape (paper section 2).

A :class:`Graph` is points, edges, boundary loops and a triangulation over the points.
:func:`build_graph` makes one from rings the paper's way: the boundary polygon, an inner
polygon offset inward, lattice points inside it, edges joining them all, points that come too
close collapsed into their neighbours, then smoothing. A user's own mesh can be its own graph:
pass its points, edges and boundary loops to :class:`Graph` directly.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .shapes import geometry_rings, nesting_depth, shape_geometry, signed_area
from .triangulate import (conforming_triangulation, edges_of_triangles, filtered_delaunay,
                          orient_counter_clockwise)
from .wording import by_count

__all__ = ["Graph", "build_graph", "default_spacing", "spacing_for"]

# Target number of lattice points for the default spacing: the paper's shapes have 160-260
# interior points (Table 1); we aim a little higher so thin limbs still get a row of points.
DEFAULT_LATTICE_POINTS = 300
# The boundary gets at most this many times as many points at the default spacing: a sliver's
# area alone asks for a spacing that lines it with tens of thousands (a bar 1e6 times longer than
# wide: 34,644 points, a minute to triangulate; 1e7: over ten minutes). Shapes with any body
# (the paper's, glyphs, traced drawings, thin limbs) have far fewer and are unchanged.
MAX_BOUNDARY_SHARE = 4
# Ring vertices closer than this fraction of the spacing are merged (see _merge_close).
NEAR_DUPLICATE = 0.01


class Graph:
    """Points joined by edges, with the shape's boundary loops and a triangulation.

    Parameters
    ----------
    points : (n, 2) array_like
        Vertex positions.
    edges : (k, 2) array_like of int
        Undirected edges. Boundary loop segments are added if missing.
    boundary_loops : sequence of 1-D array_like of int
        Each loop's vertex indices in order. Orientation is worked out from nesting and fixed:
        outer loops counter-clockwise, holes clockwise.
    triangles : (t, 3) array_like of int, optional
        A triangulation of the points; when omitted, a Delaunay triangulation restricted to the
        shape is made. Stored counter-clockwise.
    spacing : float, optional
        The lattice spacing the graph was built with (:func:`build_graph` passes it). When
        omitted (a user's own mesh, a graph read back from a file that did not store it), the
        median length of the edges joining two interior points, or of all edges when there
        are none: on the graphs :func:`build_graph` makes that median is 0.98-1.0 times the
        spacing (22 benchmark graphs, 437-5712 points).

    Attributes
    ----------
    points : (n, 2) float64 ndarray
    edges : (k, 2) int64 ndarray
    boundary_loops : list of int64 ndarray
    boundary : (m,) int64 ndarray
        All boundary vertices, loop after loop.
    interior : (n - m,) int64 ndarray
        Vertices on no boundary loop.
    triangles : (t, 3) int64 ndarray
    spacing : float
        Distance between neighbouring points away from the boundary; the energy's density
        normalisation (:class:`solver.energy.Energy`) compares it with
        :func:`default_spacing`.
    """

    def __init__(self, points, edges, boundary_loops, triangles=None, spacing=None):
        points = np.array(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2 or len(points) < 3:
            raise ValueError(f"points must be an (n, 2) array with n >= 3, got shape {points.shape}")
        if not np.all(np.isfinite(points)):
            raise ValueError("points have non-finite coordinates (NaN or inf)")
        n = len(points)
        loops = [_index_array(loop, n, f"boundary loop {i}") for i, loop in enumerate(boundary_loops)]
        if not loops:
            raise ValueError("a graph needs at least one boundary loop")
        for i, loop in enumerate(loops):
            if len(loop) < 3:
                raise ValueError(f"boundary loop {i} has fewer than 3 vertices")
        boundary = np.concatenate(loops)
        if len(np.unique(boundary)) != len(boundary):
            raise ValueError("a vertex appears twice in the boundary loops")
        self.points = points
        self.boundary_loops = _orient_loops(points, loops)
        self.boundary = np.concatenate(self.boundary_loops)

        loop_edges = np.concatenate([np.stack([loop, np.roll(loop, -1)], axis=1)
                                     for loop in self.boundary_loops])
        edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
        if len(edges) and (edges.min() < 0 or edges.max() >= n):
            raise ValueError("edges refer to points that do not exist")
        if np.any(edges[:, 0] == edges[:, 1]):
            raise ValueError("an edge joins a point to itself")
        edges = np.sort(np.concatenate([edges, loop_edges]), axis=1)
        self.edges = np.unique(edges, axis=0)
        lonely = np.setdiff1d(np.arange(n), self.edges.ravel())
        if len(lonely):
            raise ValueError(f"point {lonely[0]} has no edges ({len(lonely)} "
                             f"{by_count(len(lonely), 'such point', 'such points')})")

        on_boundary = np.zeros(n, dtype=bool)
        on_boundary[self.boundary] = True
        self.interior = np.flatnonzero(~on_boundary)

        if triangles is None:
            triangles = filtered_delaunay(points, self.geometry(), 1e-14 * self.size ** 2)
        triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        if len(triangles) and (triangles.min() < 0 or triangles.max() >= n):
            raise ValueError("triangles refer to points that do not exist")
        self.triangles = orient_counter_clockwise(points, triangles)
        if spacing is None:
            spacing = self._median_spacing()
        spacing = float(spacing)
        if not np.isfinite(spacing) or spacing <= 0:
            raise ValueError(f"spacing must be a positive number, got {spacing}")
        self.spacing = spacing

    def _median_spacing(self):
        """Median length of the edges between two interior points (all edges if none): the
        lattice spacing, for a graph built without one given."""
        inner = np.zeros(self.n, dtype=bool)
        inner[self.interior] = True
        edges = self.edges[inner[self.edges[:, 0]] & inner[self.edges[:, 1]]]
        if len(edges) == 0:
            edges = self.edges
        length = np.linalg.norm(self.points[edges[:, 0]] - self.points[edges[:, 1]], axis=1)
        spacing = float(np.median(length))
        return spacing if spacing > 0 else max(self.size, 1.0)

    @property
    def n(self):
        """Number of points."""
        return len(self.points)

    @property
    def size(self):
        """Diagonal of the bounding box: the length scale tolerances are relative to."""
        return float(np.linalg.norm(np.ptp(self.points, axis=0)))

    def area(self, positions=None):
        """Area of the shape (outer loops minus holes) at ``positions`` (rest by default)."""
        positions = self.points if positions is None else np.asarray(positions)
        return sum(signed_area(positions[loop]) for loop in self.boundary_loops)

    def geometry(self):
        """The rest shape as a shapely geometry (islands with holes)."""
        return shape_geometry([self.points[loop] for loop in self.boundary_loops])

    def adjacency(self):
        """Symmetric (n, n) CSR matrix with a 1 for every edge."""
        i, j = self.edges[:, 0], self.edges[:, 1]
        data = np.ones(2 * len(i))
        return coo_matrix((data, (np.concatenate([i, j]), np.concatenate([j, i]))),
                          shape=(self.n, self.n)).tocsr()

    def components(self):
        """Connected component label of every point, shape (n,)."""
        return connected_components(self.adjacency(), directed=False)[1]

    def __repr__(self):
        return (f"Graph({self.n} points: {len(self.boundary)} boundary in "
                f"{len(self.boundary_loops)} loops, {len(self.interior)} interior; "
                f"{len(self.edges)} edges, {len(self.triangles)} triangles)")


def _index_array(values, n, what):
    values = np.array(values, dtype=np.int64).ravel()  # a copy: the caller's may change
    if len(values) and (values.min() < 0 or values.max() >= n):
        raise ValueError(f"{what} refers to points that do not exist")
    return values


def _orient_loops(points, loops):
    """Outer loops counter-clockwise, holes clockwise, decided by nesting depth."""
    depth = nesting_depth([shapely.Polygon(points[loop]) for loop in loops])
    oriented = []
    for loop, d in zip(loops, depth):
        counter_clockwise = signed_area(points[loop]) > 0
        want_counter_clockwise = d % 2 == 0
        oriented.append(loop if counter_clockwise == want_counter_clockwise else loop[::-1].copy())
    return oriented


def default_spacing(geometry):
    """Lattice spacing giving about ``DEFAULT_LATTICE_POINTS`` points inside the shape (see
    :func:`spacing_for`)."""
    return spacing_for(geometry, DEFAULT_LATTICE_POINTS)


def spacing_for(geometry, count):
    """Lattice spacing giving about ``count`` points inside the shape ``geometry`` (a shapely
    geometry), and no more than ``MAX_BOUNDARY_SHARE`` times as many along its boundary."""
    by_area = np.sqrt(geometry.area / count)
    return float(max(by_area, geometry.length / (MAX_BOUNDARY_SHARE * count)))


def _merge_close(ring, tolerance):
    """Drop ring vertices closer than ``tolerance`` to the last one kept (keeping at least 3).

    Boolean operations and curve corners leave vertices a hair apart; each makes triangles with
    almost no area, whose orientation means nothing but whose fold penalty is huge.
    """
    previous = np.linalg.norm(ring - np.roll(ring, 1, axis=0), axis=1)
    if previous.min(initial=np.inf) >= tolerance:
        return ring
    # Greedy, so a run of close vertices keeps one every ``tolerance``; only rings that have
    # close vertices get here (plain floats: 100,000 vertices take about 50 ms).
    xs, ys = ring[:, 0].tolist(), ring[:, 1].tolist()
    keep = [0]
    for index in range(1, len(ring)):
        last = keep[-1]
        if math.hypot(xs[index] - xs[last], ys[index] - ys[last]) >= tolerance:
            keep.append(index)
    while len(keep) > 3 and math.hypot(xs[keep[-1]] - xs[0], ys[keep[-1]] - ys[0]) < tolerance:
        keep.pop()
    return ring[keep] if len(keep) >= 3 else ring


def _subdivide(ring, spacing):
    """Insert points on segments longer than ``spacing`` so the boundary is sampled evenly."""
    following = np.roll(ring, -1, axis=0)
    pieces = np.maximum(1, np.ceil(np.linalg.norm(following - ring, axis=1) / spacing).astype(np.int64))
    segment = np.repeat(np.arange(len(ring)), pieces)
    fraction = (np.arange(pieces.sum()) - np.repeat(np.cumsum(pieces) - pieces, pieces)) / np.repeat(pieces, pieces)
    return ring[segment] + fraction[:, None] * (following[segment] - ring[segment])


def _resample(ring, spacing):
    """Points evenly spaced along a closed ring, about ``spacing`` apart (at least 3)."""
    closed = np.concatenate([ring, ring[:1]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    count = int(round(arc[-1] / spacing))
    if count < 3:
        return np.empty((0, 2))
    at = np.linspace(0.0, arc[-1], count, endpoint=False)
    return np.stack([np.interp(at, arc, closed[:, 0]), np.interp(at, arc, closed[:, 1])], axis=1)


def _hexagonal_lattice(bounds, spacing):
    """Triangular lattice points (equilateral triangles of side ``spacing``) over a box."""
    x0, y0, x1, y1 = bounds
    row_step = spacing * np.sqrt(3.0) / 2.0
    ys = np.arange(y0, y1 + row_step, row_step)
    xs = np.arange(x0 - spacing, x1 + spacing, spacing)
    grid_x = xs[None, :] + 0.5 * spacing * (np.arange(len(ys)) % 2)[:, None]
    grid_y = np.broadcast_to(ys[:, None], grid_x.shape)
    return np.stack([grid_x.ravel(), grid_y.ravel()], axis=1)


def _interior_points(geometry, boundary, spacing):
    """Inner-polygon points and lattice points, with crowded points collapsed away."""
    inner = _inset(geometry, 0.5 * spacing, join_style="mitre", mitre_limit=2.0)
    inner_points = [np.empty((0, 2))]
    if not inner.is_empty:
        for island in geometry_rings(inner):
            for ring in island:
                resampled = _resample(ring, spacing)
                if len(resampled) == 0:  # a blob too small for a ring: keep one point in it
                    resampled = np.array(shapely.Polygon(ring).representative_point().coords)
                inner_points.append(resampled)
    inner_points = np.concatenate(inner_points)

    core = _inset(geometry, spacing)
    lattice = np.empty((0, 2))
    if not core.is_empty:
        lattice = _hexagonal_lattice(core.bounds, spacing)
        lattice = lattice[shapely.contains_xy(core, lattice[:, 0], lattice[:, 1])]

    # Edge collapse (paper section 2): a point closer than half a spacing to one kept before
    # it would make a short edge and slivers; merge it into that neighbour by dropping it.
    minimum = 0.5 * spacing
    kept = boundary
    result = []
    for candidates in (inner_points, lattice):
        if len(candidates) == 0:
            continue
        distance, _ = cKDTree(kept).query(candidates, distance_upper_bound=minimum)
        candidates = candidates[np.isinf(distance)]
        if len(candidates) > 1:  # inner rings of two islands can crowd each other too
            pairs = cKDTree(candidates).query_pairs(minimum, output_type="ndarray")
            candidates = np.delete(candidates, np.unique(pairs[:, 1]), axis=0)
        kept = np.concatenate([kept, candidates])
        result.append(candidates)
    return np.concatenate(result) if result else np.empty((0, 2))


def _inset(geometry, distance, **style):
    """``geometry`` shrunk by ``distance`` > 0 (a negative buffer, ``style`` as shapely's).

    Parts that hold no disc of that radius leave nothing, and are dropped first: GEOS took 7 s
    to shrink a scattered picture's 126 lacy clusters of specks to nothing, as every offset ring
    crossed hundreds of others. The largest disc a part holds is found to within a quarter of
    the radius (its centre within that of the best one's, so its radius too), a fraction of a
    millisecond for an ordinary shape."""
    parts = shapely.get_parts(geometry)
    bounds = shapely.bounds(parts)
    wide = np.flatnonzero(np.min(bounds[:, 2:] - bounds[:, :2], axis=1) > 2.0 * distance)
    slack = 0.25 * distance
    reach = shapely.length(shapely.maximum_inscribed_circle(parts[wide], slack)) if len(wide) else np.empty(0)
    holding = wide[reach + slack >= distance]
    if len(holding) == len(parts):
        return geometry.buffer(-distance, **style)
    return shapely.MultiPolygon(list(parts[holding])).buffer(-distance, **style)


def _smooth(points, first_interior, triangles, geometry, rounds=3, step=0.5):
    """Move interior points toward their neighbours' mean (umbrella smoothing)."""
    n = len(points)
    edges = edges_of_triangles(triangles)
    i, j = np.concatenate([edges[:, 0], edges[:, 1]]), np.concatenate([edges[:, 1], edges[:, 0]])
    adjacency = coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)).tocsr()
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    movable = np.arange(n) >= first_interior
    movable &= degree > 0
    points = points.copy()
    for _ in range(rounds):
        mean = (adjacency @ points) / np.maximum(degree, 1)[:, None]
        proposal = points + step * (mean - points)
        ok = movable & shapely.contains_xy(geometry, proposal[:, 0], proposal[:, 1])
        points[ok] = proposal[ok]
    return points


def build_graph(rings, spacing=None):
    """Build the paper's interior graph for a shape given by rings.

    Parameters
    ----------
    rings : sequence of (k, 2) array_like
        Closed rings in any orientation and order: outer boundaries, holes, several islands.
        Repeated points and collinear runs are fine; vertices closer than ``NEAR_DUPLICATE``
        times the spacing are merged.
    spacing : float, optional
        Distance between interior lattice points; also the longest boundary segment (longer
        ones are subdivided). By default about 300 lattice points fill the shape.

    Returns
    -------
    Graph

    Raises
    ------
    ValueError
        Malformed rings (see :func:`solver.shapes.shape_geometry`) or a non-positive spacing.
    """
    geometry = shape_geometry(rings)
    if spacing is None:
        spacing = default_spacing(geometry)
    spacing = float(spacing)
    if not np.isfinite(spacing) or spacing <= 0:
        raise ValueError(f"spacing must be a positive number, got {spacing}")
    # Built about the shape's centre and moved back at the end: points subdivided along a slanted
    # edge of a shape a millionth of its offset in size land off the edge by the offset's
    # rounding, and the nearly flat triangles they make at the boundary wreck binding and the
    # fold penalty.
    x0, y0, x1, y1 = geometry.bounds
    origin = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
    geometry = shapely.transform(geometry, lambda xy: xy - origin)

    loops = [_subdivide(_merge_close(ring, NEAR_DUPLICATE * spacing), spacing)
             for island in geometry_rings(geometry) for ring in island]
    boundary = np.concatenate(loops)
    interior = _interior_points(geometry, boundary, spacing)
    points, loop_indices, triangles = conforming_triangulation(loops, interior, geometry)

    first_interior = sum(len(loop) for loop in loop_indices)
    if len(points) > first_interior:
        points = _smooth(points, first_interior, triangles, geometry)
        loops = [points[index] for index in loop_indices]
        points, loop_indices, triangles = conforming_triangulation(
            loops, points[first_interior:], geometry)
    return Graph(points + origin, edges_of_triangles(triangles), loop_indices, triangles, spacing=spacing)
