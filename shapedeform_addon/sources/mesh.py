# SPDX-License-Identifier: GPL-3.0-or-later
"""Planar meshes: the graph is the mesh itself (small, well-shaped meshes) or built inside its
outline; the mesh is never written (its Shape Deform modifier shows the pose).

``sd_rest`` is where an older version kept the rest positions while it wrote poses into the
mesh; :func:`restore_legacy` gives them back when such a rig is unbound.
"""

import numpy as np

from ... import solver
from ...solver.outline import outline_graph
from ...solver.rigging.outline import boundary_loops, smallest_angles
from ...solver.rigging.plane import fit_plane
from ..errors import RigError
from .prepared import Prepared

REST_ATTRIBUTE = "sd_rest"
# The automatic graph mode deforms the mesh itself up to this many vertices; denser meshes are
# bound to a graph of a few hundred points built from their outline (a solve stays fast).
OWN_GRAPH_LIMIT = 2000
# ... and only when its triangles are not slivers (text and n-gon fills are): the paper's energy
# on slivers lets them flip, while a built graph has well-shaped triangles.
OWN_GRAPH_MIN_ANGLE = np.radians(5.0)


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
    flat = plane.to_2d(rest)
    tris = triangles(mesh)
    try:
        loops = boundary_loops(tris)
    except ValueError as err:
        raise RigError(f"'{obj.name}' cannot be rigged: {err}") from None
    on_faces = np.zeros(len(rest), dtype=bool)
    on_faces[tris.ravel()] = True
    mode = settings.graph_mode
    well_shaped = smallest_angles(flat, tris).min() >= OWN_GRAPH_MIN_ANGLE
    if mode == "AUTO":
        mode = "OWN" if len(rest) <= OWN_GRAPH_LIMIT and on_faces.all() and well_shaped else "OUTLINE"
    try:
        if mode == "OWN":
            if not on_faces.all():
                raise ValueError(f"{int((~on_faces).sum())} vertices are on no face; use the Outline graph")
            graph = solver.Graph(flat, edges(mesh), loops, tris)
        else:
            rings = [flat[loop] for loop in loops]
            graph = outline_graph(rings, settings.density)
    except ValueError as err:
        raise RigError(f"'{obj.name}' cannot be rigged: {err}") from None
    advice = ""
    if not well_shaped:
        advice = ("its long thin faces can fold where it bends hard: raise Refine on its Shape Deform "
                  "modifier to subdivide them")
    return Prepared(plane, graph, advice=advice)


def unbind(obj):
    """Give back what binding changed; what could not be, as phrases (see :mod:`.sources`)."""
    return []


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
    mesh = obj.data
    mask = np.zeros(len(mesh.vertices), dtype=bool)
    mesh.vertices.foreach_get("select", mask)
    return positions(mesh)[mask].astype(np.float64)
