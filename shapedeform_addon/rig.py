# SPDX-License-Identifier: GPL-3.0-or-later
"""The runtime cache of rigs, and posing: handle transforms in, the cage's pose out.

:class:`Rig` holds the solver objects of one owner, rebuilt lazily from what the .blend keeps
(:mod:`.rig_format`). Its owner is this module's ``_cache``, keyed by ``Object.session_uid``; an
entry is stale when the owner's handles or settings change (:func:`signature`, or
:func:`invalidate`) and is dropped by :func:`forget` (after load, undo or redo), or when a new
rig is cached after its owner left the file. Posing writes only the cage, a
few hundred points; the object's Shape Deform modifier maps its own points through it.

Coarse copies of graphs (:class:`solver.CoarseCopies`) are kept in ``_coarse_copies`` for every
rig: they are keyed by the graph's points and outline, so they stay valid across undo and
reloading, and a rebuilt rig skips making them again (most of a rebuild's time). As many are
kept as rigs were ever cached at once, so undo, which rebuilds them all, finds every one (with
a fixed 32, a scene of 40 rigs remade all 40 on every undo).

Rigs the viewport does not show are not solved while the animation plays or scrubs
(:func:`defer`); they are posed when it stops, with the unsettled ones.

A rig remembers its last solve: a frame whose handles give the same targets (a rig nobody
animated, during playback) reuses it, since a pose depends on its targets alone.

Settings an animator may key or drive (energy weights, budgets, pin amounts) are read where the
depsgraph being posed keeps them (:func:`_animated`): a render's depsgraph holds the frame's
values in its evaluated copies only.
"""

import traceback

import bpy
import numpy as np

from .. import solver
from ..solver.rigging import depth
from ..solver.rigging.handles import frame_2d, region_targets
from ..solver.rigging.plane import affine_inverse
from . import rig_format
from .errors import RigError

_cache = {}
_coarse_copies = solver.CoarseCopies(kept=32)
# Owners (session_uid) whose pose was left as it was while hidden during playback (:func:`defer`).
_deferred = set()


class Rig:
    """Solver objects of one rig owner, rebuilt from its stored data."""

    def __init__(self, obj, depsgraph=None):
        if rig_format.is_legacy(obj):
            raise RigError(f"'{obj.name}' was bound by an older version of Shape Deform; "
                           "unbind it (its rest shape comes back) and bind it again")
        settings = obj.shapedeform
        if settings.cage is None or not len(settings.cage.data.vertices):
            raise RigError(lost_cage(obj))
        self.coarse_copies = _coarse_copies
        self._last_solve = None  # (iterations, targets' bytes, positions, converged)
        self._last_cage = None  # (positions' and pin amounts' bytes, cage points)
        self.plane, self.graph = rig_format.read_graph(obj)
        if len(settings.cage.data.vertices) != self.graph.n:
            raise RigError(f"'{obj.name}': its cage '{settings.cage.name}' was edited; unbind it and bind it again")
        items = rig_format.handle_items(obj)
        self.handle_objects = [empty for empty, _, _ in items]
        self.indices = np.concatenate([i for _, i, _ in items]) if items else np.empty(0, np.int64)
        self.offsets = np.concatenate([o for _, _, o in items]) if items else np.empty((0, 2))
        self.owners = np.concatenate([np.full(len(i), k) for k, (_, i, _) in enumerate(items)]) \
            if items else np.empty(0, np.int64)
        values = _animated(obj, depsgraph).shapedeform
        weights = {"laplacian": values.weight_laplacian, "mvc": values.weight_mvc, "edge": values.weight_edge}
        stiffness = self._stiffness(obj, depsgraph)
        try:
            self.deformer = solver.Deformer(self.graph, self.indices, weights, values.preserve_area,
                                            prevent_flips=values.prevent_flips,
                                            coarse_copies=self.coarse_copies, stiffness=stiffness) \
                if len(self.indices) else None
        except solver.UncoveredPoints as err:
            raise RigError(f"'{obj.name}': {err.explain(_weight_label)}") from None
        except ValueError as err:
            raise RigError(f"'{obj.name}': {_in_interface_terms(err)}") from None
        overlap = rig_format.pin_items(obj, "OVERLAP")
        self.overlap_pins = [empty for empty, _ in overlap]
        extents = _finite([_animated(empty, depsgraph).shapedeform.extent for empty, _ in overlap],
                          self.overlap_pins, "Extent")
        self.overlap_reach = depth.pin_weights(self.graph.points, self.graph.edges, [point for _, point in overlap],
                                               extents * self.graph.size)
        self.in_front = np.zeros(len(overlap))
        self.edge_lengths = depth.edge_lengths(self.graph.points, self.graph.edges)  # for cage_points
        self.signature = signature(obj, depsgraph)
        # The pose shown (the cage's, as saved or last written): graph positions (n, 2) and the
        # cage's points (n, 3) in rig space, lifted where it overlaps itself; and whether it is
        # what a render gives (converged, or solved with the Render budget).
        self.follow_cage(settings.cage)
        self.settled = True

    def follow_cage(self, cage):
        """Take the pose ``cage`` shows now (a bake's at this frame, or as saved) as the shown one."""
        self.shown = rig_format.shown_pose(cage).astype(np.float32)
        self.posed = self.plane.to_2d(self.shown)
        if not np.all(np.isfinite(self.posed)):
            self.posed = self.graph.points.copy()
            self.shown = self.cage_points(self.posed)

    def frames(self, obj, depsgraph=None):
        """Each handle's 2D frame in the shape's plane, (h, 3, 3), from evaluated transforms."""
        cage = _evaluated(obj.shapedeform.cage, depsgraph)
        handles = [_evaluated(h, depsgraph) for h in self.handle_objects]
        return np.array([frame_2d(self.plane, _relative(h, cage)) for h in handles]).reshape(-1, 3, 3)

    def solve(self, frames, iterations):
        """Graph positions (n, 2) for handle frames (h, 3, 3); ``settled`` tells whether the
        solve converged (the pose is then the one a render gives)."""
        if self.deformer is None:
            self.settled = True
            return self.graph.points.copy()
        targets = region_targets(frames, self.offsets, self.owners)
        # The deformer and its tolerance are fixed for the rig's life: the targets and the budget
        # decide the solve, so the same pair gives the same pose.
        last = self._last_solve
        if last is not None and last[:2] == (iterations, targets.tobytes()):
            self.settled = last[3]
            return last[2].copy()
        solution = self.deformer.solve(targets, max_iterations=iterations)
        self.settled = solution.converged
        self._last_solve = (iterations, targets.tobytes(), solution.positions.copy(), solution.converged)
        return solution.positions

    def _stiffness(self, obj, depsgraph=None):
        """Per graph point, 1 plus each starch pin's stiffness times its reach; None without pins.
        Keeps the pins' reach (``starch_reach``, (k, n)) and amounts (``starch``, (k,))."""
        items = rig_format.pin_items(obj, "STARCH")
        pins = [(_animated(empty, depsgraph).shapedeform, point) for empty, point in items]
        empties = [empty for empty, _ in items]
        extents = _finite([pin.extent for pin, _ in pins], empties, "Extent")
        self.starch_reach = depth.pin_weights(self.graph.points, self.graph.edges, [point for _, point in pins],
                                              extents * self.graph.size)
        self.starch = _finite([pin.stiffness for pin, _ in pins], empties, "Stiffness")
        return depth.stiffness(self.starch, self.starch_reach)

    def pin_amounts(self, depsgraph=None):
        """The overlap pins' current amounts (k,)."""
        return np.array([_animated(p, depsgraph).shapedeform.in_front for p in self.overlap_pins], dtype=np.float64)

    def cage_points(self, positions):
        """The cage's points (n, 3) float32 in rig space for graph ``positions`` (n, 2), lifted
        off the plane so that where the pose overlaps itself one layer is in front."""
        # A rig nobody moves gets the same positions on every frame (QA: the depth took 1.1 ms of
        # each still rig's frame).
        key = (positions.tobytes(), self.in_front.tobytes())
        if self._last_cage is not None and self._last_cage[0] == key:
            return self._last_cage[1].copy()
        graph = self.graph
        score = depth.moved_score(graph.points, positions, graph.size) * \
            depth.automatic_reach(positions, graph.triangles, self.edge_lengths, graph.size)
        lift = depth.heights(score, graph.size, self.in_front, self.overlap_reach)
        points = self.plane.to_3d(positions, lift).astype(np.float32)
        self._last_cage = (key, points)
        return points.copy()


def _finite(values, pins, label):
    """``values`` (k,) float64, the pins' ``label`` values; RigError naming the pins where one
    is not a finite number (only Python can set one so)."""
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    bad = [pin.name for pin, value in zip(pins, values) if not np.isfinite(value)]
    if bad:
        raise RigError(f"{', '.join(repr(name) for name in bad)}: its {label} is not a finite number")
    return values


def _weight_label(term):
    """The sidebar's name of an energy term's weight ("Boundary Detail" for "laplacian")."""
    settings = bpy.types.Object.bl_rna.properties["shapedeform"].fixed_type
    return f"'{settings.properties['weight_' + term].name}'"


def signature(obj, depsgraph=None):
    """What the deformer depends on besides stored data: handles, settings (as ``depsgraph``
    has them, see :func:`_animated`), and which cage it writes (a cage removed or edited by
    hand makes the rig rebuild, which says so)."""
    s = obj.shapedeform
    values = _animated(obj, depsgraph).shapedeform
    cage = (s.cage.session_uid, len(s.cage.data.vertices)) if s.cage is not None else None
    return (cage, tuple(_handle_signature(item.object, depsgraph) for item in rig_format.present_items(obj)),
            values.weight_laplacian, values.weight_mvc, values.weight_edge, values.preserve_area, values.prevent_flips,
            rig_format.path_carries_rig(obj))


def lost_cage(obj):
    """What to say of a bound ``obj`` whose cage is gone, wherever it is found (QA: Bake and the
    status told it two ways)."""
    return (f"'{obj.name}' is bound but lost its cage (deleted by hand, its rig unbound, or bound by an older "
            "version): unbind it and bind it again")


def _path_carries_handles(obj):
    """What to say of a curve ``obj`` whose Path Animation was turned on after binding."""
    return (f"'{obj.name}': Path Animation was turned on after binding, and carries the handles (children of "
            "the curve) along its path, away from the shape: turn it off (Object Data > Path Animation); to have "
            "objects ride the path, parent them to the curve or give them a Follow Path or Clamp To constraint, then "
            "unbind and bind again (the handles then follow it by constraints)")


# The solver's parameters its messages name, as the sidebar labels them.
_INTERFACE_NAMES = {"preserve_area": "Preserve Area"}


def _in_interface_terms(error):
    """A solver error's message with its parameters called what the sidebar calls them."""
    message = str(error)
    for parameter, label in _INTERFACE_NAMES.items():
        message = message.replace(parameter, label)
    return message


def _handle_signature(empty, depsgraph):
    pin = _animated(empty, depsgraph).shapedeform
    return empty.name, pin.pin_kind, pin.extent, pin.stiffness if pin.pin_kind == "STARCH" else None


def get(obj, depsgraph=None):
    """The :class:`Rig` of ``obj``'s rig owner, built if missing or stale (for the settings
    ``depsgraph`` has); RigError if it cannot be."""
    owner = rig_format.owner_of(obj.original)
    if owner is None:
        raise RigError(f"'{obj.name}' is not bound")
    rig = _cache.get(owner.session_uid)
    if rig is None or rig.signature != signature(owner, depsgraph):
        if rig is None:
            _drop_removed()
        _coarse_copies.kept = max(_coarse_copies.kept, len(_cache) + 1)
        rig = Rig(owner, depsgraph)
        _cache[owner.session_uid] = rig
    return rig


def as_shown(obj):
    """:func:`get`, with the rig's ``shown`` and ``posed`` the pose on screen: a baked rig
    plays its keys and is not posed, so its last solve (of another frame, or a bake's) is not
    what the cage shows; what is drawn over it and handles added on it take the bake's."""
    rig = get(obj)
    owner = rig_format.owner_of(obj.original)
    if rig_format.is_baked(owner):
        rig.follow_cage(owner.shapedeform.cage)
    return rig


def _drop_removed():
    """Drop the rigs of owners no longer in the file (deleted without an undo or a reload
    since): a batch that binds, poses and deletes objects kept every one (8 MB each)."""
    live = {obj.session_uid for obj in rig_format.bound_objects()}
    for uid in [uid for uid in _cache if uid not in live]:
        del _cache[uid]
    _deferred.intersection_update(live)


def stale(obj):
    """Whether the cached rig of owner ``obj`` no longer fits its handles, settings or overlap
    pins' amounts (a driver or keyed value can change them without any update callback). A rig
    not cached (none built yet, or dropped by undo) is not stale: it is built when something
    poses it."""
    cached = _cache.get(obj.original.session_uid)
    return cached is not None and (cached.signature != signature(obj.original)
                                   or not np.array_equal(cached.in_front, cached.pin_amounts()))


def invalidate(obj):
    """Have the cached rig of ``obj`` rebuilt on next use, reusing its coarse copies (handles or
    settings changed; the graph did not)."""
    cached = _cache.get(obj.original.session_uid)
    if cached is not None:
        cached.signature = None


def forget(obj=None):
    """Drop the cached rig of ``obj`` (of every object when None): rebuilt on next use."""
    if obj is None:
        _cache.clear()
    else:
        _cache.pop(obj.original.session_uid, None)


def _evaluated(obj, depsgraph):
    return obj.evaluated_get(depsgraph) if depsgraph is not None else obj


def _animated(obj, depsgraph):
    """Where ``obj``'s keyable settings are read: the original (the active depsgraph writes a
    frame's animated values back to it, and a sidebar edit is there before any depsgraph has
    seen it), or, for a render's depsgraph (which writes nothing back), its evaluated copy."""
    return obj.evaluated_get(depsgraph) if depsgraph is not None and depsgraph.mode == "RENDER" else obj


def _relative(obj, space):
    """The transform (4, 4) of ``obj`` in the space of object ``space``.

    Handles and the cage are children of the rig's owner: where neither has constraints, the
    product of their own transforms gives it without the owner's, which an owner scaled to zero
    along an axis in the plane (a card flip) cannot be inverted to recover (its least-squares
    inverse put every handle on one line)."""
    def own(o):
        return np.array(o.matrix_parent_inverse, dtype=np.float64) @ np.array(o.matrix_basis, dtype=np.float64)

    if (obj.parent is not None and obj.parent == space.parent and obj.parent_type == space.parent_type == "OBJECT"
            and not any(c.enabled for c in obj.constraints) and not any(c.enabled for c in space.constraints)):
        return affine_inverse(own(space)) @ own(obj)
    # An object scaled to zero keeps its other axes.
    return affine_inverse(np.array(space.matrix_world, dtype=np.float64)) @ np.array(obj.matrix_world, dtype=np.float64)


def final_quality():
    """Whether solves are for keeps: baking, rendering, or Blender without a window."""
    return bpy.app.background or bpy.app.is_job_running("RENDER")


def _far_handle(rig, frames):
    """Which handle, if one, is so far from the shape that a solve overflows: ": its handle 'X'
    is 1e+30 shape sizes away" (from the middle of the shape's rest), else ""."""
    if not len(frames):
        return ""
    away = np.abs(frames[:, :2, 2] - rig.graph.points.mean(axis=0)).max(axis=1) / rig.graph.size
    far = int(np.argmax(away))
    return f": its handle '{rig.handle_objects[far].name}' is {away[far]:.3g} shape sizes away" \
        if away[far] > 1e6 else ""


def handle_frames(obj, depsgraph=None):
    """The handles' 2D frames (h, 3, 3) of ``obj``'s rig as ``depsgraph`` evaluated them."""
    return get(obj).frames(rig_format.owner_of(obj.original), depsgraph)


def pose(obj, depsgraph=None, final=None):
    """Solve for the handles' current transforms and write the pose into the owner's cage.

    ``final`` picks the Render iteration budget over the Viewport one; by default it is
    :func:`final_quality`. A baked rig is solved but its cage keeps playing the bake.

    Raises
    ------
    RigError
        The rig cannot be built or the solve failed; nothing was written.
    """
    owner = rig_format.owner_of(obj.original)
    if owner is not None and rig_format.path_carries_rig(owner):
        invalidate(owner)  # so that the update turning it off again poses the rig
        raise RigError(_path_carries_handles(owner))
    if owner is not None and owner.shapedeform.cage is not None:
        rig_format.follow_library_cage(owner.shapedeform.cage)  # here, never while drawing
    rig = get(obj, depsgraph)
    frames = rig.frames(owner, depsgraph)
    _finite(np.abs(frames).max(axis=(1, 2)), rig.handle_objects, "transform")
    settings = owner.shapedeform
    budgets = _animated(owner, depsgraph).shapedeform
    final = final_quality() if final is None else final
    rig.in_front = _finite(rig.pin_amounts(depsgraph), rig.overlap_pins, "In Front")
    try:
        positions = rig.solve(frames, budgets.render_iterations if final else budgets.iterations)
        points = rig.cage_points(positions)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError) as err:
        far = _far_handle(rig, frames) if isinstance(err, FloatingPointError) else ""
        raise RigError(f"'{owner.name}': {_in_interface_terms(err)}{far}") from None
    if not np.all(np.isfinite(points)):
        raise RigError(f"'{owner.name}': the solve gave non-finite positions{_far_handle(rig, frames)}")
    rig.settled = rig.settled or final
    if not rig_format.is_baked(owner):
        rig_format.write_pose(settings.cage, np.ascontiguousarray(points), rig.settled)
    rig.posed, rig.shown = positions, points
    _deferred.discard(owner.session_uid)
    return rig


def defer(obj):
    """Leave owner ``obj``'s pose as it is for now (the viewport does not show it while the
    animation plays): :func:`unsettled` lists it until it is posed."""
    _deferred.add(obj.original.session_uid)


def unsettled(scene, owners=None):
    """Rig owners of ``scene`` (or of ``owners``, when the caller has them) whose shown pose is
    not what a render gives: a Viewport-budget solve that did not converge (also one an undo
    step brought back, marked on its cage), or one :func:`defer` left behind."""
    owners = rig_format.owners(scene) if owners is None else owners
    return [obj for obj in owners if obj.session_uid in _deferred or (
        not _cache[obj.session_uid].settled if obj.session_uid in _cache else rig_format.is_unsettled(obj))]


def pose_safely(obj, depsgraph=None, final=None):
    """:func:`pose`, keeping the last good pose and recording why when it fails.

    The last line of defence of the handlers, which pose every rig of a scene in turn: any
    error is caught, so one rig that fails leaves the others posed. Errors other than RigError
    (saved data a script edited, or a fault of the extension) have their traceback printed,
    and the status says so.

    Returns
    -------
    str
        Empty when it worked, else the reason (also in the owner's ``shapedeform.status``).
    """
    owner = rig_format.owner_of(obj.original) or obj
    try:
        pose(obj, depsgraph, final)
        message = ""
    except RigError as err:
        message = str(err)
    except Exception as err:  # the cage is written last, once all went well: it keeps its last pose
        traceback.print_exc()
        message = (f"'{owner.name}' could not be posed ({type(err).__name__}: {err}; the system console has "
                   "the details): if a script edited its rig's saved data, Undo; else please report it")
    if not message and not rig_format.modifiers_of(owner):
        message = (f"'{owner.name}' lost its Shape Deform modifier (applied, removed, or converted): "
                   "its handles no longer move it; Unbind removes the rig and keeps the shape")
        try:  # the modifier's group is a placeholder of a missing library's
            rig_format.require_posable(owner, "its handles move it again")
        except RigError as err:
            message = str(err)
    if owner.shapedeform.status != message:
        owner.shapedeform.status = message
    return message
