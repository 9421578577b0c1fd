# SPDX-License-Identifier: GPL-3.0-or-later
"""Planar meshes: the graph is the mesh itself (small, well-shaped meshes) or built inside its
outline; the mesh's points are never written (its Shape Deform modifier shows the pose).

A mesh that is its own graph with several islands gets a hidden point attribute,
:data:`ISLAND`: each vertex's island number (see :mod:`..nodes`). Blender carries it
through Edit Mode, Separate, shape keys and the modifier's subdivision, so overlapping islands
(a cut-out puppet's arm over its body) stay apart whatever the vertices' indices and places
become; unbind removes it.

``sd_rest`` is where an older version kept the rest positions while it wrote poses into the
mesh; :func:`restore_legacy` gives them back when such a rig is unbound.
"""

import functools
import typing

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ... import solver
from ...solver.outline import outline_graph, parts_graph
from ...solver.shapes import geometry_rings
from ...solver.triangulate import triangle_cross
from ...solver.wording import by_count
from ...solver.rigging.outline import boundary_loops, smallest_angles, with_area, wound_alike
from ...solver.rigging.depth import pin_reaches
from ...solver.rigging.plane import affine_inverse, fit_plane, transform_points
from .. import compat, nodes, rig_format
from ..errors import RigError
from ..nodes import ISLAND
from .prepared import Prepared

REST_ATTRIBUTE = "sd_rest"
# The automatic graph mode deforms the mesh itself up to this many vertices; denser meshes are
# bound to a graph of a few hundred points built from their outline (a solve stays fast).
OWN_GRAPH_LIMIT = 2000
# ... and only when its triangles are not slivers (text and n-gon fills are): the paper's energy
# on slivers lets them flip, while a built graph has well-shaped triangles.
OWN_GRAPH_MIN_ANGLE = np.radians(5.0)
# ... and only when most of its points are inside: a mesh that is little but its outline
# (Blender's Plane: four corners, no inside) gives the energy's interior terms nothing to hold,
# and a handle's region of a few points spans most of it (a corner's handle took three corners).
# Unless its faces overlap (a cut-out puppet's pieces): only the mesh itself keeps them apart.

# Places closer than this fraction of the mesh's size are one place: faces' edges lying on one
# another are joined (_welded); a speck so small between faces is no hole (_outline_graph).
COINCIDENT = 1e-6


def read_vectors(attribute, count):
    """A float vector attribute as a (count, 3) float32 array."""
    flat = np.empty(count * 3, dtype=np.float32)
    attribute.data.foreach_get("vector", flat)
    return flat.reshape(count, 3)


def positions(mesh):
    """The mesh's vertex positions, (v, 3) float32."""
    return read_vectors(mesh.attributes["position"], len(mesh.vertices))


def triangles(mesh):
    """Its faces as triangles, (t, 3) int64 vertex indices."""
    mesh.calc_loop_triangles()
    flat = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", flat)
    return flat.reshape(-1, 3).astype(np.int64)


def edges(mesh):
    """Its edges, (e, 2) int64 vertex indices."""
    flat = np.empty(len(mesh.edges) * 2, dtype=np.int32)
    mesh.edges.foreach_get("vertices", flat)
    return flat.reshape(-1, 2).astype(np.int64)


def _welded(rest, flat, tris, mesh_edges):
    """The mesh with its faces joined where their edges lie on one another (within
    :data:`COINCIDENT` of its size): a mesh whose faces share no vertices (an OBJ import, Edge
    Split) is one piece, not an island per face. Islands that only overlap (a puppet's arm over
    its body) stay apart, even where a vertex of one lies on a vertex of the other. (Where
    joined faces meet at a corner only, :func:`prepare` rigs the outline.) Returns (flat points
    (p, 2), triangles, edges, each vertex's point (n,)): the mesh as it is when nothing joins."""
    size = float(np.linalg.norm(np.ptp(rest, axis=0)))
    pairs = cKDTree(rest).query_pairs(COINCIDENT * size, output_type="ndarray")
    # Corners of one triangle are never joined (a strip a million times longer than wide is
    # that thin: it lost every face).
    n = len(rest)
    corner_pairs = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    pairs = pairs[~np.isin(pairs[:, 0] * n + pairs[:, 1], corner_pairs[:, 0] * n + corner_pairs[:, 1])]
    unjoined = (flat, tris, mesh_edges, np.arange(n))
    if len(pairs) == 0:
        return unjoined
    _, place = connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)),
                                    directed=False)
    sides, uses = np.unique(corner_pairs, axis=0, return_counts=True)
    open_sides = sides[uses == 1]
    _, side_place, lying = np.unique(np.sort(place[open_sides], axis=1), axis=0, return_inverse=True,
                                     return_counts=True)
    joined = np.zeros(n, dtype=bool)
    joined[open_sides[lying[side_place.ravel()] > 1].ravel()] = True  # on an edge that lies on another
    if not joined.any():
        return unjoined
    _, label = np.unique(np.where(joined, place, place.max() + 1 + np.arange(n)), return_inverse=True)
    label = label.ravel()
    first = np.zeros(label.max() + 1, dtype=np.int64)
    first[label[::-1]] = np.arange(n)[::-1]  # each merged point's first vertex
    merged = label[tris]
    merged = merged[(merged[:, 0] != merged[:, 1]) & (merged[:, 1] != merged[:, 2]) & (merged[:, 0] != merged[:, 2])]
    edges_merged = np.sort(label[mesh_edges], axis=1)
    edges_merged = np.unique(edges_merged[edges_merged[:, 0] != edges_merged[:, 1]], axis=0)
    return flat[first], merged, edges_merged, label


def prepare(obj, settings):
    """Read the object's rest shape and build its graph, changing nothing (see :mod:`.sources`)."""
    mesh = obj.data
    if len(mesh.vertices) == 0:
        raise RigError(f"'{obj.name}' has no vertices")
    rest = positions(mesh)
    try:
        plane = fit_plane(rest)
    except ValueError as err:
        raise RigError(f"'{obj.name}' cannot be rigged: {err}") from None
    flat, tris, mesh_edges, vertex_point = _welded(rest, plane.to_2d(rest), triangles(mesh), edges(mesh))
    if len(tris) == 0:
        raise RigError(f"'{obj.name}' cannot be rigged: it has no faces")
    try:
        loops, pinched = boundary_loops(tris), None
    except ValueError as err:  # faces meeting at a corner only: the outline still has a shape
        loops, pinched = None, err
    on_faces = np.zeros(len(flat), dtype=bool)
    on_faces[tris.ravel()] = True
    mode = settings.graph_mode
    well_shaped = smallest_angles(flat, tris).min() >= OWN_GRAPH_MIN_ANGLE
    # Islands that overlap one another (a low-poly puppet's arm quad over its body quad) get an
    # outline graph each, kept apart; where the mesh is its own graph a part had its corners
    # alone, too few points for a second handle.
    face_islands, point_islands = _mesh_islands(flat, tris)
    cover = functools.cache(functools.partial(_island_cover, flat, tris, loops, face_islands, point_islands))
    parts = _overlapping_islands(face_islands, cover) if pinched is None and mode != "OWN" else None
    if mode == "AUTO":
        own = len(flat) <= OWN_GRAPH_LIMIT and on_faces.all() and well_shaped and pinched is None
        if own and 2 * sum(len(loop) for loop in loops) >= len(flat):  # mostly outline
            own = parts is None and cover().overlap
        mode = "OWN" if own else "OUTLINE"
    point_part = None
    try:
        if mode == "OWN":
            if pinched is not None:
                raise ValueError(f"{pinched}; use the Outline graph")
            if not on_faces.all():
                loose = int((~on_faces).sum())
                raise ValueError(f"{loose} {by_count(loose, 'vertex is', 'vertices are')} on no face; use the "
                                 "Outline graph")
            graph = solver.Graph(flat, mesh_edges, loops, tris)
        elif parts is not None:
            point_part = np.zeros(len(flat), dtype=np.int64)  # a loose vertex follows the first part's map
            point_part[tris] = parts[:, None]
            graph, part = parts_graph([[flat[loop] for loop in boundary_loops(tris[parts == k])]
                                       for k in range(parts.max() + 1)], settings.density)
        else:
            graph = _outline_graph(flat, tris, loops, settings.density)
    except ValueError as err:
        raise RigError(f"'{obj.name}' cannot be rigged: {err}") from None
    advice = ""
    if not well_shaped:
        advice = ("its long thin faces can fold where it bends hard: raise Refine on its Shape Deform "
                  "modifier to subdivide them")
    if point_part is not None:
        numbers = rig_format.island_numbers(np.arange(parts.max() + 1), obj.data)
        islands, vertex_islands = numbers[part], numbers[point_part[vertex_point]]
    else:
        islands = _islands(graph, obj.data) if mode == "OWN" else None
        vertex_islands = None if islands is None else islands[vertex_point]
    if islands is None:
        return Prepared(plane, graph, advice=advice)
    return Prepared(plane, graph, lambda o: mark_islands(o, vertex_islands), advice=advice, islands=islands)


def _overlapping_islands(parts, cover):
    """Each triangle's island ``parts`` (t,) where the mesh's islands overlap one another, none
    overlapping itself; else None. ``cover()`` is the mesh's :class:`_Cover`."""
    if parts.max() == 0:
        return None
    cover = cover()
    return parts if cover.overlap and not cover.island_overlaps else None


def _outline_graph(flat, tris, loops, density):
    """The graph of the outline of the faces (t, 3) over points (n, 2): their boundary loops
    (None when pinched or closed), or, where those bound no sensible shape, the union of the
    faces as the plane shows them (a bevelled curve converted to a mesh is a closed tube)."""
    if loops is not None:
        rings = [flat[loop] for loop in loops]
        try:
            return outline_graph(with_area(rings) or rings, density)  # a flat face's loop left out
        except ValueError:
            pass
    faces = shapely.union_all(shapely.polygons(flat[tris]))
    gap = COINCIDENT * float(np.linalg.norm(np.ptp(flat, axis=0)))
    # Faces meeting edge to edge leave specks of rounding between them (1e-11 across) in the union.
    rings = [ring for island in geometry_rings(faces) for ring in island if np.ptp(ring, axis=0).max() > gap]
    return outline_graph(rings, density)


def _islands(graph, data):
    """Each graph point's island number (n,) int32 for a rig of mesh ``data``
    (:func:`rig_format.island_numbers`); None when the graph is one piece."""
    pieces = graph.components()
    return rig_format.island_numbers(pieces, data) if pieces.max() > 0 else None


def overlap_pin_notes(obj, rig, point, extent):
    """A pin lifts the mesh's own vertices: on a low-poly mesh (a quad per part) all of them may
    lie beyond its reach, unless the modifier's Refine cuts the faces first (QA: a pin on a quad
    arm's middle left the arm in front). Said only where the mesh's own vertices are what the
    rig gets: no modifier before it (a Subdivision Surface's points may be reached), not in
    Edit Mode (the mesh's data lags behind the edit)."""
    modifiers = rig_format.modifiers_of(obj)
    if not modifiers or not len(obj.data.vertices) or obj.mode == "EDIT":
        return []
    before = list(obj.modifiers)[:list(obj.modifiers).index(modifiers[0])]
    if any(m.show_viewport or m.show_render for m in before):
        return []
    if compat.modifier_input(modifiers[0], nodes.input_identifiers(modifiers[0].node_group)[nodes.REFINE_INPUT]):
        return []
    to_rig = affine_inverse(rig_format.rig_to_object(obj))
    vertices = rig.plane.to_2d(transform_points(to_rig, positions(obj.data)))
    graph = rig.graph
    if pin_reaches(graph.points, graph.edges, point, extent, vertices, graph.spacing):
        return []
    return [f"the overlap pin reaches none of '{obj.name}''s vertices, and a lift moves only those: raise the "
            "modifier's Refine to cut its faces (or the pin's Extent)"]


def mark_islands(obj, islands, domain="POINT", data_type="INT"):
    """Write each vertex's (or a grease pencil's layer's, ``domain`` "LAYER") island number
    (k,) into ``obj``'s data as :data:`ISLAND` (another rig of this data may have written it:
    it is made anew)."""
    attributes = obj.data.attributes
    if attributes.get(ISLAND) is not None:
        attributes.remove(attributes[ISLAND])
    attributes.new(ISLAND, data_type, domain).data.foreach_set("value", np.asarray(islands, dtype=np.int32))


class _Cover(typing.NamedTuple):
    """How the faces of a mesh lie in its plane: whether some lie on others, and whether some of
    those are of one island."""

    overlap: bool
    island_overlaps: bool


def _mesh_islands(flat, tris):
    """Each triangle's island (t,) int64 and each point's (n,) int64 (the points on no face all
    one number, one past the islands'), for triangles (t, 3) over points (n, 2)."""
    sides = tris[:, [0, 1, 1, 2]].reshape(-1, 2)
    _, labels = connected_components(coo_matrix((np.ones(len(sides)), (sides[:, 0], sides[:, 1])),
                                                shape=(len(flat), len(flat))), directed=False)
    island_labels, parts = np.unique(labels[tris[:, 0]], return_inverse=True)
    numbers = np.full(labels.max() + 1, len(island_labels), dtype=np.int64)
    numbers[island_labels] = np.arange(len(island_labels))
    return parts.ravel(), numbers[labels]


def _island_cover(flat, tris, loops, parts, point_parts):
    """The :class:`_Cover` of the triangles (t, 3) over points (n, 2) in islands ``parts`` (t,)
    and ``point_parts`` (n,) (:func:`_mesh_islands`), whose boundary loops are ``loops`` (None
    where they do not split into simple loops).

    An island whose faces, wound alike, turn one way in the plane and whose boundary loops bound
    as much area as its faces covers what the loops bound, once: only the loops need uniting,
    not every triangle (QA: uniting 100,000 triangles took 3.2 s, so meshes over 2,000 vertices
    were not asked, and their overlapping islands were joined into one outline)."""
    count = parts.max() + 1
    cross = triangle_cross(flat, wound_alike(tris))  # a face with its normal flipped still turns as its island
    areas = 0.5 * np.bincount(parts, weights=np.abs(cross), minlength=count)
    one_way = (np.bincount(parts, weights=cross > 0.0, minlength=count) == 0) \
        | (np.bincount(parts, weights=cross < 0.0, minlength=count) == 0)
    loops = list(loops or ())
    loop_parts = point_parts[[loop[0] for loop in loops]] if loops else np.zeros(0, dtype=np.int64)
    shapes = _loop_covers(flat, loops, loop_parts, one_way, areas)
    island_tris = _grouped(parts, count)
    self_overlap = False
    for k in [k for k in range(count) if shapes[k] is None]:  # the faces themselves decide
        shapes[k] = shapely.union_all(shapely.polygons(flat[tris[island_tris[k]]]))
        self_overlap |= shapes[k].area < areas[k] * (1.0 - 1e-6)
    covered = shapely.union_all(shapes).area if count > 1 else shapes[0].area
    return _Cover(self_overlap or covered < areas.sum() * (1.0 - 1e-6), self_overlap)


def _grouped(labels, count):
    """The indices of each of ``count`` labels in ``labels`` (k,): a list of ``count`` arrays."""
    order = np.argsort(labels, kind="stable")
    return np.split(order, np.cumsum(np.bincount(labels, minlength=count))[:-1])


def _loop_covers(flat, loops, loop_parts, one_way, areas):
    """Per island (``areas`` (c,) of its faces, ``one_way`` (c,) whether they turn one way), the
    polygon its boundary ``loops`` bound (the largest its shell, the rest its holes) where that
    covers its faces once, all made at once; None elsewhere. (c,) object array."""
    shapes = np.full(len(areas), None, dtype=object)
    chosen = np.flatnonzero(one_way[loop_parts])
    if not len(chosen):
        return shapes
    lengths = np.array([len(loops[i]) for i in chosen])
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    points = np.concatenate([flat[loops[i]] for i in chosen])
    following = np.arange(1, len(points) + 1)
    following[starts + lengths - 1] = starts  # each loop's last point is followed by its first
    x, y = points.T
    loop_areas = 0.5 * np.abs(np.add.reduceat(x * y[following] - x[following] * y, starts))
    island = loop_parts[chosen]
    order = np.lexsort((-loop_areas, island))  # by island, its shell first
    rings = shapely.linearrings(points, indices=np.repeat(np.arange(len(chosen)), lengths))[order]
    islands, dense = np.unique(island[order], return_inverse=True)
    polygons = shapely.polygons(rings, indices=dense.ravel())
    kept = shapely.is_valid(polygons) & (np.abs(shapely.area(polygons) - areas[islands]) <= 1e-6 * areas[islands])
    shapes[islands[kept]] = polygons[kept]
    return shapes


def unbind(obj):
    """Give back what binding changed; what could not be, as phrases (see :mod:`.sources`)."""
    forget_islands(obj)
    return []


def forget_islands(obj):
    """Remove the vertices' islands (:data:`ISLAND`) from ``obj``'s mesh unless another rig still
    deforms it (a linked duplicate following the rig, another rig of the data): the last of
    them removes them. Also for a mesh no rig deforms that got them by Join (which merges
    attributes)."""
    attribute = obj.data.attributes.get(ISLAND)
    if attribute is not None and not rig_format.other_rigged_users(obj):
        obj.data.attributes.remove(attribute)


def restore_legacy(obj):
    """Write an older version's saved rest points back (see :mod:`.sources`)."""
    mesh = obj.data
    attribute = mesh.attributes.get(REST_ATTRIBUTE)
    if attribute is None or attribute.domain != "POINT" or attribute.data_type != "FLOAT_VECTOR":
        return [f"the rest shape (attribute {REST_ATTRIBUTE} is gone or changed; the vertices stay where they are)"]
    rest = read_vectors(attribute, len(mesh.vertices))
    mesh.attributes.remove(attribute)
    mesh.attributes["position"].data.foreach_set("vector", rest.ravel())
    mesh.update()
    return []


def selected(obj):
    """Local rest positions (k, 3) of the selected vertices (call in Object Mode)."""
    return positions(obj.data)[_selection(obj.data)].astype(np.float64)


def selected_islands(obj):
    """Each selected vertex's island number (k,) int32, in :func:`selected`'s order (0: not known,
    a vertex added since binding), or None where the mesh keeps none (call in Object Mode)."""
    islands = rig_format.islands_of(obj.data)
    return None if islands is None else islands[_selection(obj.data)]


def _selection(mesh):
    """Which vertices (v,) bool are selected."""
    mask = np.zeros(len(mesh.vertices), dtype=bool)
    mesh.vertices.foreach_get("select", mask)
    return mask
