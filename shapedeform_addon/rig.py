# SPDX-License-Identifier: GPL-3.0-or-later
"""Rigs: binding and unbinding objects, and the runtime cache that poses them.

What lives in the .blend (so a saved file keeps working with no step by hand):

- the source's rest points (``sd_rest`` attributes, or ID properties on curves),
- on ``obj.shapedeform`` as ID properties: ``plane`` (12 numbers) and the graph
  (``graph_points``, ``graph_edges``, ``graph_loops`` with ``graph_loop_sizes``,
  ``graph_triangles``, ``own_graph``), stored rather than rebuilt so that a file opens with
  exactly the graph it was rigged with,
- on each handle item: ``indices`` (graph points it owns) and ``offsets`` (those points in the
  handle's frame when it was added).

What lives only in memory (:class:`Rig`, keyed by ``Object.session_uid``): the solver's graph,
deformer and binding, rebuilt lazily from the above after load, undo, or a settings change.
"""

import bpy
import numpy as np

from .. import solver
from ..solver.rigging.handles import frame_2d, region_targets
from ..solver.rigging.plane import Plane
from . import sources
from .sources import RigError

_cache = {}


class Rig:
    """Solver objects of one bound object, rebuilt from its stored rest data.

    ``previous``, the rig this one replaces (handles or settings changed), hands on its coarse
    copies of the graph (:class:`solver.CoarseCopies`, keyed by the graph's points, so a copy
    is only reused for the same shape): rebuilding after a handle edit then skips building them.
    """

    def __init__(self, obj, previous=None):
        settings = obj.shapedeform
        self.coarse_copies = previous.coarse_copies if previous is not None else solver.CoarseCopies()
        self.source = sources.module_for(obj)
        rest = self.source.read_rest(obj)
        try:
            self.plane = Plane.from_array(settings["plane"])
            n = len(settings["graph_points"]) // 2
            points = np.asarray(settings["graph_points"], dtype=np.float64).reshape(n, 2)
            loops = np.split(np.asarray(settings["graph_loops"], dtype=np.int64),
                             np.cumsum(np.asarray(settings["graph_loop_sizes"]))[:-1])
            self.graph = solver.Graph(points, np.asarray(settings["graph_edges"]).reshape(-1, 2),
                                      loops, np.asarray(settings["graph_triangles"]).reshape(-1, 3))
            self.own_graph = bool(settings["own_graph"])
        except (KeyError, ValueError) as err:
            raise RigError(f"'{obj.name}' has damaged rig data ({err}); unbind and bind it again") from None
        self.rest_flat = self.plane.to_2d(rest)
        self.heights = self.plane.heights(rest)
        if self.own_graph and len(rest) != self.graph.n:
            raise RigError(f"'{obj.name}' changed its point count since it was bound; unbind and bind it again")
        self.binding = None if self.own_graph else solver.bind(self.graph, self.rest_flat)
        self.handle_objects = []
        indices, offsets, owners = [], [], []
        for item in settings.handles:
            if not _present(item.object) or "indices" not in item:
                continue  # the animator deleted the Empty: that handle is gone
            owned = np.asarray(item["indices"], dtype=np.int64)
            indices.append(owned)
            offsets.append(np.asarray(item["offsets"], dtype=np.float64).reshape(-1, 2))
            owners.append(np.full(len(owned), len(self.handle_objects)))
            self.handle_objects.append(item.object)
        self.indices = np.concatenate(indices) if indices else np.empty(0, np.int64)
        self.offsets = np.concatenate(offsets) if offsets else np.empty((0, 2))
        self.owners = np.concatenate(owners) if owners else np.empty(0, np.int64)
        weights = {"laplacian": settings.weight_laplacian, "mvc": settings.weight_mvc, "edge": settings.weight_edge}
        try:
            self.deformer = solver.Deformer(self.graph, self.indices, weights, settings.preserve_area,
                                            prevent_flips=settings.prevent_flips,
                                            coarse_copies=self.coarse_copies) \
                if len(self.indices) else None
        except ValueError as err:
            raise RigError(f"'{obj.name}': {err}") from None
        self.signature = signature(obj)
        # Graph positions of the last pose written (rest until posed), and whether that pose is
        # what a render gives: converged, or solved with the Render budget.
        self.posed = self.graph.points.copy()
        self.settled = True

    def frames(self, obj, depsgraph=None):
        """Each handle's 2D frame in the shape's plane, (h, 3, 3), from evaluated transforms."""
        def world(o):
            o = o.evaluated_get(depsgraph) if depsgraph is not None else o
            return np.array(o.matrix_world, dtype=np.float64)

        to_local = np.linalg.inv(world(obj))
        return np.array([frame_2d(self.plane, to_local @ world(h)) for h in self.handle_objects]).reshape(-1, 3, 3)

    def solve(self, frames, iterations):
        """Graph positions (n, 2) for handle frames (h, 3, 3); ``settled`` tells whether the
        solve converged (the pose is then the one a render gives)."""
        if self.deformer is None:
            self.settled = True
            return self.graph.points.copy()
        targets = region_targets(frames, self.offsets, self.owners)
        solution = self.deformer.solve(targets, max_iterations=iterations)
        self.settled = solution.converged
        return solution.positions

    def points(self, positions):
        """The source's points, (p, 3) float32, for graph ``positions`` (n, 2)."""
        flat = positions if self.binding is None else self.binding.apply(positions)
        return self.plane.to_3d(flat, self.heights).astype(np.float32)


def _present(handle):
    """A handle Empty that still exists in a scene.

    Deleting an object in the viewport only unlinks it: the handle's pointer keeps it alive
    as an orphan, so "deleted by hand" means "in no scene".
    """
    return handle is not None and len(handle.users_scene) > 0


def signature(obj):
    """What the deformer depends on besides stored data: handles and settings."""
    s = obj.shapedeform
    return (tuple(item.object.name if _present(item.object) else None for item in s.handles),
            s.weight_laplacian, s.weight_mvc, s.weight_edge, s.preserve_area, s.prevent_flips)


def get(obj):
    """The object's :class:`Rig`, built if missing or stale; RigError if it cannot be."""
    obj = obj.original
    rig = _cache.get(obj.session_uid)
    if rig is None or rig.signature != signature(obj):
        rig = Rig(obj, previous=rig)
        _cache[obj.session_uid] = rig
    return rig


def forget(obj=None):
    """Drop the cached rig of ``obj`` (of every object when None): rebuilt on next use."""
    if obj is None:
        _cache.clear()
    else:
        _cache.pop(obj.original.session_uid, None)


def final_quality():
    """Whether solves are for keeps: baking, rendering, or Blender without a window."""
    return bpy.app.background or bpy.app.is_job_running("RENDER")


def pose(obj, depsgraph=None, final=None):
    """Solve for the handles' current transforms and write the result into ``obj``.

    ``final`` picks the Render iteration budget over the Viewport one; by default it is
    :func:`final_quality`.

    Raises
    ------
    RigError
        The rig cannot be built or the solve failed; nothing was written.
    """
    rig = get(obj)
    frames = rig.frames(obj, depsgraph)
    settings = obj.shapedeform
    final = final_quality() if final is None else final
    try:
        positions = rig.solve(frames, settings.render_iterations if final else settings.iterations)
        points = rig.points(positions)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError) as err:
        raise RigError(f"'{obj.name}': {err}") from None
    if not np.all(np.isfinite(points)):
        raise RigError(f"'{obj.name}': the solve gave non-finite positions; kept the last pose")
    rig.source.write(obj, np.ascontiguousarray(points))
    rig.posed = positions
    rig.settled = rig.settled or final
    return rig


def unsettled(scene):
    """Bound objects of ``scene`` whose shown pose stopped short of what a render gives (a
    Viewport-budget solve that did not converge)."""
    return [obj for obj in bound_objects(scene)
            if not getattr(_cache.get(obj.session_uid), "settled", True)]


def pose_safely(obj, depsgraph=None, final=None):
    """:func:`pose`, keeping the last good pose and recording why when it fails.

    Returns
    -------
    str
        Empty when it worked, else the reason (also in ``obj.shapedeform.status``).
    """
    try:
        pose(obj, depsgraph, final)
        message = ""
    except RigError as err:
        message = str(err)
    if obj.shapedeform.status != message:
        obj.shapedeform.status = message
    return message


# -- binding ----------------------------------------------------------------------------------

def _store_graph(settings, plane, graph, own_graph):
    settings["plane"] = plane.to_array()
    settings["graph_points"] = graph.points.ravel()
    settings["graph_edges"] = graph.edges.astype(np.int32).ravel()
    settings["graph_loops"] = np.concatenate(graph.boundary_loops).astype(np.int32)
    settings["graph_loop_sizes"] = np.array([len(loop) for loop in graph.boundary_loops], dtype=np.int32)
    settings["graph_triangles"] = graph.triangles.astype(np.int32).ravel()
    settings["own_graph"] = bool(own_graph)


_STORED_KEYS = ("plane", "graph_points", "graph_edges", "graph_loops", "graph_loop_sizes",
                "graph_triangles", "own_graph")


def bind(obj):
    """Rig ``obj``: everything is computed first, so a refusal changes nothing.

    Raises
    ------
    RigError
        The object cannot be rigged; the message says why.
    """
    if obj is None:
        raise RigError("No active object to rig")
    settings = obj.shapedeform
    if settings.is_bound:
        raise RigError(f"'{obj.name}' is already bound")
    if settings.rig is not None:
        raise RigError(f"'{obj.name}' is a handle of '{settings.rig.name}'")
    kind = sources.kind_of(obj)
    module = sources.module_for(obj)
    prepared = module.prepare(obj, settings)
    prepared.commit(obj)
    _store_graph(settings, prepared.plane, prepared.graph, prepared.own_graph)
    settings.kind = kind
    settings.is_bound = True
    for scene in obj.users_scene:
        # Frame handlers pose rigs while a render reads the scene from another thread: lock the
        # interface during renders (saved in the file, so farm and F12 renders are safe).
        scene.render.use_lock_interface = True
    settings.status = ""
    forget(obj)
    return get(obj)


def unbind(obj):
    """Give back the rest shape exactly and remove everything the rig added: bake, data, handles.

    The bake goes too (as *Clear Bake* removes it): left behind it would keep playing the
    deformation over the object's own shape, and its mark would keep a new rig on the object
    from ever posing it.

    A broken rig (a grease-pencil keyframe it deforms deleted, its rest data gone) is unbound
    too: what can be given back is, and the rest is returned to be told to the user. The
    handles go last, once the rest shape is back, so a failure never leaves a rig without them.

    A linked duplicate (its data shared with another bound object) gives up only its own rig:
    the shared data keeps the other rig's rest data and bake.

    Returns
    -------
    list of str
        What could not be given back, as phrases for a message (empty when all was).

    Raises
    ------
    RigError
        ``obj`` is not bound; nothing was changed.
    """
    from . import bake, handles

    settings = obj.shapedeform
    if not settings.is_bound:
        raise RigError(f"'{obj.name}' is not bound")
    source = sources.module_for(obj)
    if shares_data(obj) is None:
        # Before the restore: the bake's keys (a mesh's shape keys, a curve's F-curves) sit on
        # the data the restore writes.
        bake.clear(obj)
        lost = source.restore(obj)
    else:
        # A linked duplicate (Alt+D): the data is also the other object's, whose rig still
        # deforms and bakes it; its rest data and bake stay, only this object's rig goes.
        for key in (bake.BAKED, bake.GP_FRAMES, "gp_layers", "gp_frames"):
            settings.pop(key, None)
        settings.original_data = None
        lost = []
    for key in _STORED_KEYS:
        if key in settings:
            del settings[key]
    settings.is_bound = False
    settings.kind = ""
    settings.status = ""
    handles.remove_all(obj)
    forget(obj)
    return lost


def shares_data(obj):
    """Another bound object whose data is ``obj``'s (a linked duplicate), or None."""
    return next((o for o in bpy.data.objects
                 if o != obj and o.data is not None and o.data == obj.data and o.shapedeform.is_bound), None)


def rigged_object(context):
    """The object the user means: the active object, or the rig of an active handle."""
    obj = context.active_object
    if obj is not None and obj.shapedeform.rig is not None:
        return obj.shapedeform.rig
    return obj


def bound_objects(scene):
    """Bound objects of ``scene``."""
    return [o for o in scene.objects if o.shapedeform.is_bound]
