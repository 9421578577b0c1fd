# SPDX-License-Identifier: GPL-3.0-or-later
"""Handles: ordinary Empty objects, one collection per rig, parented to the rigged object.

A handle's Empty is parented to the shape's object (so moving the object carries its rig;
except on curves bound with path animation on, which would carry children along the path) and
drawn as a circle in the shape's plane, as big as the region of the shape it owns. The rig's
collection also holds its cage (hidden).
"""

import bpy
import numpy as np
from mathutils import Matrix

from ..solver.rigging.handles import (MIN_REGION_POINTS, distance_off, frame_2d, handle_matrix, place,
                                      region_offsets, select_region)
from ..solver.rigging.plane import affine_inverse
from . import compat, rig_format, sources
from . import rig as rigs
from .errors import NoPointsLeft, RigError


FOLLOW = "Shape Deform"  # the constraint by which a handle follows a curve with path animation


# Constraints that set the space a transform lives in, as a parent does (Blender's transform
# reads such a space off the evaluated matrices too).
PARENTING_CONSTRAINTS = {"CHILD_OF", "ARMATURE", "FOLLOW_PATH", "CLAMP_TO", "OBJECT_SOLVER", "FOLLOW_TRACK"}


def parent_space(handle):
    """World matrix (4, 4) of the space a handle's own transform lives in.

    Its parent object's (times the parent inverse), or the world's; under a bone or vertex
    parent or a parenting constraint (Child Of, the curve follower's among them), read off the
    evaluated matrices as ``matrix_world @ matrix_basis^-1`` where the handle's own transform
    can be inverted (constraints that only turn or limit it leave the parent's space as it is)."""
    basis = np.array(handle.matrix_basis, dtype=np.float64)
    parenting = handle.parent is not None and handle.parent_type != "OBJECT"
    parenting |= any(c.enabled and c.type in PARENTING_CONSTRAINTS for c in handle.constraints)
    if parenting and np.linalg.matrix_rank(basis[:3, :3]) == 3:
        return np.array(handle.matrix_world, dtype=np.float64) @ affine_inverse(basis)
    if handle.parent is not None:
        return np.array(handle.parent.matrix_world, dtype=np.float64) @ np.array(handle.matrix_parent_inverse)
    return np.eye(4)


def set_active(settings, index):
    """Make item ``index`` the list's active handle without selecting its Empty: only a pick in
    the sidebar's list selects (the property's update), not the add-on's own bookkeeping, which
    may run inside another mode's operator."""
    settings["active_handle"] = max(int(index), 0)


def follow_active_object(view_layer):
    """Make the active object, when it is a handle or pin of a rig, its list's active item, as
    Blender's lists follow the active bone or material slot (a click in the viewport picks it,
    and the sidebar shows and removes what was clicked); nothing is selected. True when the
    item changed."""
    empty = view_layer.objects.active
    owner = rig_of(empty) if empty is not None and empty.type == "EMPTY" else None
    if owner is None or owner.library is not None:  # a linked rig's list is the library's
        return False
    settings = owner.shapedeform
    index = next((i for i, item in enumerate(settings.handles) if item.object == empty), None)
    if index is None or index == settings.active_handle:
        return False
    set_active(settings, index)
    return True


def collection(obj):
    """The collection of ``obj``'s rig (handles and cage), made when missing."""
    settings = obj.shapedeform
    collection = settings.handle_collection
    if collection is None:
        collection = bpy.data.collections.new(f"{obj.name} Handles")
        parents = obj.users_collection or (bpy.context.scene.collection,)
        parents[0].children.link(collection)
        settings.handle_collection = collection
    return collection


def add(obj, location, on_rest=False, kind="POSITION", notes=None, island=0, snap=False):
    """Add a handle at a world ``location`` (projected onto the shape's plane).

    The handle owns the graph points near the place on the rest shape that is now under
    ``location`` (or, with ``on_rest``, that ``location`` is at on the unposed shape), on one
    piece of the graph (islands that overlap stay apart): ``island``'s, else the piece of the
    layer there nearest ``location``'s depth as shown (in front for a location under them
    all), else, off the shape, the nearest point's (:func:`_piece`). Their offsets are taken
    from their current (posed) positions, so adding a handle does not move the shape.

    A pin (``kind`` 'OVERLAP' or 'STARCH') pulls nothing: it is bound to the graph point under
    ``location`` and vertex-parented to that point of the cage, so it follows the shape.

    A handle placed further off the shape than its region's radius holds the nearest part at a
    distance, as a lever: ``notes`` (a list), when given, gets a sentence saying so.

    ``island``, where known, is the island number of the vertex ``location`` is at (see
    ``sources.selected_islands``; 0: not known). With ``snap``, a ``location`` off the shape
    puts the handle on the shape's nearest point instead.

    Returns
    -------
    bpy.types.Object
        The new Empty.

    Raises
    ------
    RigError
        The object is not bound, or no graph point is left for the handle.
    """
    settings = obj.shapedeform
    if not settings.is_bound:
        raise RigError(f"'{obj.name}' is not bound: bind it first")
    rig_format.require_local(obj, "add handles")
    rig = rigs.as_shown(obj)
    world = rig_format.rig_space(obj)
    graph = rig.graph
    point, rest_centre, triangle = _place(obj, rig, location, on_rest, snap)
    pieces, piece = _piece(obj, graph, triangle, island)
    if kind != "POSITION":
        if notes is not None and distance_off(rig.posed, graph.triangles, point) > 1e-4 * graph.size:
            notes.append(f"the {kind.lower()} pin was added off the shape: it is on the shape's nearest point")
        on = _pin_point(graph, rest_centre, pieces, piece)
        pin = _add_pin(obj, rig, on, kind)
        if notes is not None and kind == "OVERLAP":
            notes.extend(sources.overlap_pin_notes(obj, rig, on, pin.shapedeform.extent * graph.size))
        return pin
    taken = np.zeros(graph.n, dtype=bool)
    taken[rig.indices] = True
    try:
        region = select_region(graph.points, rest_centre, settings.region_size * graph.size, taken,
                               pieces=pieces, piece=piece)
    except ValueError as err:  # every point is taken
        raise NoPointsLeft(f"{err} (lower Handle Region, or bind again with a higher Graph Density for more "
                           "points)") from None
    radius = settings.region_size * graph.size
    matrix = handle_matrix(rig.plane, point)
    offsets = region_offsets(frame_2d(rig.plane, matrix), rig.posed[region])

    empty = _new_handle_empty(obj, world @ matrix, radius)
    empty.shapedeform.rig = obj
    off = distance_off(rig.posed, graph.triangles, point)
    if notes is not None and off > radius:
        notes.append(f"'{empty.name}' is {off / graph.size:.0%} of the shape's size off it: it holds the "
                     "nearest part at a distance")
    item = settings.handles.add()
    item.object = empty
    item[rig_format.HANDLE_INDICES] = region.astype(np.int32)
    item[rig_format.HANDLE_OFFSETS] = offsets.ravel()
    set_active(settings, len(settings.handles) - 1)
    rig_format.keep_handles_evaluated(obj)
    rigs.invalidate(obj)
    return empty


def _place(obj, rig, location, on_rest=False, snap=False):
    """:func:`~solver.rigging.handles.place` for owner ``obj``'s rig at world ``location``."""
    graph = rig.graph
    try:
        return place(rig.plane, rig_format.rig_space(obj), location, graph.points, rig.posed, graph.triangles,
                     on_rest, posed_heights=rig.plane.heights(rig.shown), snap=snap, rank=sources.part_ranks(obj))
    except ValueError as err:
        raise RigError(f"'{obj.name}': {err}") from None


def _pin_point(graph, rest_centre, pieces, piece):
    """The graph point a pin rides on: the one of ``piece`` nearest ``rest_centre`` (2,)."""
    return int(select_region(graph.points, rest_centre, 0.0, minimum=1, pieces=pieces, piece=piece)[0])


def _piece(obj, graph, triangle, island):
    """Each graph point's piece (n,) and the piece a handle is on: ``island`` (a vertex's
    island number) where the cage keeps the islands, else that of ``triangle``, the graph's
    triangle under the handle (None: not known; the region's nearest point's piece is taken)."""
    islands = rig_format.islands_of(obj.shapedeform.cage.data) if island else None
    if islands is not None and np.any(islands == island):
        return islands, island
    pieces = graph.components()
    return pieces, None if triangle is None else pieces[graph.triangles[triangle, 0]]


def _new_handle_empty(obj, world_matrix, radius):
    """A handle's Empty at ``world_matrix`` (4x4), parented so it follows the owner."""
    empty = bpy.data.objects.new(f"{obj.name} Handle", None)
    empty.empty_display_type = "CIRCLE"
    empty.empty_display_size = radius
    collection(obj).objects.link(empty)
    local = affine_inverse(np.array(obj.matrix_world, dtype=np.float64)) @ world_matrix  # in the owner's space
    if rig_format.follows_by_constraint(obj):
        # A curve with path animation carries its children along the path (and a child would
        # depend on the geometry the rig makes): follow its transform alone, by constraint, as
        # its cage does.
        follow = empty.constraints.new("CHILD_OF")
        follow.name, follow.target = FOLLOW, obj
        follow.inverse_matrix.identity()
        empty.matrix_basis = Matrix(local.tolist())
    else:
        # Its own transform in rig space (:func:`keep_in_rig_space`). Matrices, not lists: a
        # nested list would be read column by column.
        empty.parent = obj
        to_object = rig_format.rig_to_object(obj)
        empty.matrix_parent_inverse = Matrix(to_object.tolist())
        empty.matrix_basis = Matrix((affine_inverse(to_object) @ local).tolist())
    return empty


def add_all(obj, locations, kind="POSITION", on_rest=False, notes=None, islands=None):
    """:func:`add` at each of ``locations`` (k, 3), all or none: the Empties added, or RigError
    with none left behind. ``islands`` (k,), where known, are the island numbers of the vertices
    they are at."""
    added = []
    islands = np.zeros(len(locations), dtype=np.int64) if islands is None else islands
    active = obj.shapedeform.active_handle  # each add makes its handle the active item
    try:
        for location, island in zip(locations, islands):
            added.append(add(obj, location, on_rest=on_rest, kind=kind, notes=notes, island=int(island)))
    except RigError as err:
        if added:
            remove(obj, set(added))
            set_active(obj.shapedeform, active)
        if isinstance(err, NoPointsLeft) and len(locations) > 1:  # say how many fit, and what to do
            raise NoPointsLeft(f"{len(added)} of the {len(locations)} handles asked for fit (each holds "
                               f"{MIN_REGION_POINTS} or more points of the shape); select fewer points. None was "
                               "added") from None
        raise
    return added


def keep_in_rig_space(obj):
    """Keep the own transforms of ``obj``'s handles in rig space, where their keys were made;
    True when something changed.

    Apply Transform (or Set Origin) on the owner keeps each child where it is by writing its
    place into its own transform and clearing its parent inverse: a handle's keys, in rig space,
    then played in the owner's new space (Apply Scale moved a keyed handle 0.5 on a shape 3
    wide). A handle's parent inverse is kept at the map from rig space to the owner's space (the
    cage's own transform), so its own transform stays in rig space: the place Apply wrote is
    taken back there, and its keys mean what they did.
    """
    cage = obj.shapedeform.cage
    if cage is None or cage.parent != obj:
        return False
    to_object = rig_format.rig_to_object(obj)
    if abs(np.linalg.det(to_object[:3, :3])) < 1e-12:
        return False
    changed = False
    for item in obj.shapedeform.handles:
        handle = item.object
        if handle is None or handle.library is not None or handle.override_library is not None \
                or handle.parent != obj or handle.parent_type != "OBJECT":
            continue
        inverse = np.array(handle.matrix_parent_inverse, dtype=np.float64)
        if np.allclose(inverse, to_object, rtol=0.0, atol=1e-6 * max(np.abs(to_object).max(), 1.0)):
            continue
        own = affine_inverse(to_object) @ inverse @ np.array(handle.matrix_basis, dtype=np.float64)
        handle.matrix_parent_inverse = Matrix(to_object.tolist())
        _set_own_transform(handle, Matrix(own.tolist()))
        changed = True
    return changed


def _set_own_transform(handle, matrix):
    """Set ``handle``'s own transform to ``matrix`` (4x4), an Euler rotation written as near the
    angles it had as the new turn allows, as Blender's Apply Transform writes its children's:
    setting the matrix writes the turn one way of those that make it (-pi for pi), and a key
    on one of its channels (Z keyed, X and Y not) would then play with the others written
    anew. (Quaternions and axis-angles come out of Apply Transform written one way already:
    -q for q.)"""
    euler = handle.rotation_euler.copy()
    handle.matrix_basis = matrix
    if handle.rotation_mode not in ("QUATERNION", "AXIS_ANGLE"):
        handle.rotation_euler = handle.rotation_euler.to_matrix().to_euler(handle.rotation_mode, euler)


def _add_pin(obj, rig, point, kind):
    empty = bpy.data.objects.new(f"{obj.name} {kind.title()} Pin", None)
    empty.empty_display_type = "SPHERE" if kind == "OVERLAP" else "CUBE"
    collection(obj).objects.link(empty)
    empty.shapedeform.rig = obj
    empty.shapedeform.pin_kind = kind
    empty.parent = obj.shapedeform.cage
    empty.parent_type = "VERTEX"
    empty.parent_vertices = (point, 0, 0)
    empty.matrix_parent_inverse.identity()
    item = obj.shapedeform.handles.add()
    item.object = empty
    item[rig_format.PIN_POINT] = point
    set_active(obj.shapedeform, len(obj.shapedeform.handles) - 1)
    rig_format.keep_handles_evaluated(obj)
    fit_pin_shapes(obj, rig)
    rigs.invalidate(obj)
    return empty


def left_its_point(pin):
    """Whether ``pin`` (an overlap or starch pin's Empty) was moved off the cage point it rides
    on by hand: its own location is no longer zero, and no key or driver sets it."""
    return (pin.shapedeform.pin_kind != "POSITION" and pin.parent_type == "VERTEX" and any(pin.location)
            and pin.library is None and not compat.is_animated(pin, "location"))


def reseat_pins(obj):
    """Put each pin of owner ``obj``'s rig that was moved by hand (:func:`left_its_point`) on
    the shape's point under where it was left, as After Effects moves a pin: the point it is
    bound to, its vertex parent and its location are set anew (the layer nearest its depth
    where the pose overlaps itself; the nearest point of the shape when left off it).

    Returns
    -------
    bool
        Whether any pin is bound to another point now (the rig is then rebuilt on next use).

    Raises
    ------
    RigError
        The rig is a library's: its pins were put back on their points.
    """
    moved = [item for item in rig_format.present_items(obj)
             if rig_format.PIN_POINT in item and left_its_point(item.object)]
    if not moved:
        return False
    refusal = rig_format.local_refusal(obj, "move its pins")
    if refusal:  # the library keeps which points they ride on: back on theirs
        for item in moved:
            item.object.location = (0.0, 0.0, 0.0)
        raise RigError(refusal)
    rig = rigs.as_shown(obj)
    changed = False
    for item in moved:
        pin = item.object
        _, rest_centre, triangle = _place(obj, rig, pin.matrix_world.translation, snap=True)
        pieces, piece = _piece(obj, rig.graph, triangle, 0)
        point = _pin_point(rig.graph, rest_centre, pieces, piece)
        changed |= point != item[rig_format.PIN_POINT]
        item[rig_format.PIN_POINT] = point
        pin.parent_vertices = (point, 0, 0)
        pin.location = (0.0, 0.0, 0.0)
    if changed:
        rigs.invalidate(obj)
    return changed


def put_pins_back(obj):
    """Put the pins of owner ``obj``'s rig that an older version left off their points (where
    moving a pin's Empty moved nothing) back on them, as they pose; what a user moves from now
    on re-seats (:func:`reseat_pins`). Called when a file is opened."""
    for item in rig_format.present_items(obj):
        if rig_format.PIN_POINT in item and left_its_point(item.object):
            item.object.location = (0.0, 0.0, 0.0)


def fit_pin_shapes(obj, rig=None):
    """Size the sphere or cube of each pin of owner ``obj``'s rig to show its extent on the
    shape as the viewport shows it, the object's scale included (riding on a cage point, a pin's
    Empty takes none of it).

    Parameters
    ----------
    obj : bpy.types.Object
        A rig owner.
    rig : rig.Rig, optional
        Its rig, when the caller has it (by default the cached one, built if missing; a rig
        that cannot be built is left as it is: posing it says why).
    """
    pins = [item.object for item in rig_format.present_items(obj)
            if item.object.shapedeform.pin_kind != "POSITION" and item.object.library is None]
    if not pins:
        return
    try:
        rig = rig if rig is not None else rigs.get(obj)
    except Exception:  # called from a handler, which must not raise: posing the rig says why
        return
    in_plane = rig_format.rig_space(obj)[:3, :3] @ rig.plane.axes[:2].T
    # The geometric mean of the two scales in the plane: one size for a sphere, which a scale
    # not the same along both axes stretches into no sphere.
    size = rig.graph.size * max(np.linalg.det(in_plane.T @ in_plane), 0.0) ** 0.25
    for pin in pins:
        wanted = pin.shapedeform.extent * size
        if not np.isclose(pin.empty_display_size, wanted, rtol=1e-6):  # a write evaluates again
            pin.empty_display_size = wanted


def keep_in_collection(obj):
    """Link back into ``obj``'s handle collection the handles and pins moved out of it (M, Move
    to Collection); True when any was.

    The rig's collection then still holds all of its handles, to show, hide or select together
    (Blender evaluates them wherever the object is whatever their collections:
    ``rig_format.keep_handles_evaluated``). A handle in no collection was deleted, and stays so.
    """
    settings = obj.shapedeform
    home = settings.handle_collection
    if obj.library is not None or home is None or home.library is not None or home.override_library is not None:
        return False
    kept = set(home.objects)
    strays = [item.object for item in settings.handles
              if item.object is not None and item.object not in kept and rig_format.present(item.object)]
    for empty in strays:
        home.objects.link(empty)
    return bool(strays)


def locked_by_override(obj):
    """The present handles and pins of ``obj``'s rig that a library override holds as system
    overrides: Blender's interface will not move or key them (it makes only armatures editable
    when it overrides a Collection Instance)."""
    return [item.object for item in rig_format.present_items(obj)
            if item.object.override_library is not None
            and item.object.override_library.is_system_override]


def owns(obj, empty):
    """Whether ``empty`` is a handle made for ``obj``'s own rig.

    Every handle Empty names its rig (``empty.shapedeform.rig``, set by :func:`add`). A
    duplicate of a rigged object (Shift+D without its handles) copies the handle list, which
    then points at the original's Empties: those belong to the original, not to the copy.
    """
    return empty is not None and empty.shapedeform.rig == obj.original


def remove(obj, empties, deleted_too=False):
    """Drop the handles whose Empties are in ``empties``; returns how many were removed.

    Only Empties ``obj`` owns (:func:`owns`) are deleted; an entry pointing at another rig's
    handle is only dropped from the list, so unbinding a duplicate never breaks the original.
    The entries of handles deleted for good (their Empty gone), which the list shows as deleted
    until the user removes them, go too with ``deleted_too`` (the user's Remove Handle), and
    only then: taking back a handle the add-on made (a cancelled drag's pin, a refused
    multi-add) leaves the list as it found it. RigError for a library's rig (nothing is
    changed).
    """
    rig_format.require_local(obj, "remove handles")
    settings = obj.shapedeform
    removed = 0
    for i in reversed(range(len(settings.handles))):
        empty = settings.handles[i].object
        if empty in empties or (deleted_too and empty is None):
            settings.handles.remove(i)
            if empty is not None:
                if owns(obj, empty):
                    bpy.data.objects.remove(empty)
                removed += 1
    set_active(settings, min(settings.active_handle, max(len(settings.handles) - 1, 0)))
    rig_format.keep_handles_evaluated(obj)
    rigs.invalidate(obj)
    return removed


def remove_all(obj):
    """Remove every handle of ``obj`` and its handle collection, when no other rig uses it."""
    settings = obj.shapedeform
    remove(obj, {item.object for item in settings.handles}, deleted_too=True)
    collection = settings.handle_collection
    if collection is not None:
        for leftover in list(collection.objects):
            if owns(obj, leftover):
                bpy.data.objects.remove(leftover)
        settings.handle_collection = None
        # A duplicate's pointer may name the original's collection: keep a collection that
        # still holds anything or that another object's rig still puts its handles in.
        shared = any(o.shapedeform.handle_collection == collection for o in bpy.data.objects)
        if len(collection.objects) == 0 and len(collection.children) == 0 and not shared:
            bpy.data.collections.remove(collection)


def listed(obj, empty):
    """Whether ``empty`` is in the handle list of ``obj``'s rig (a copy of a handle is not)."""
    return any(item.object == empty for item in obj.shapedeform.handles)


def rig_of(empty):
    """The rig owner a handle Empty (or a cage) belongs to, or None."""
    owner = empty.shapedeform.rig
    return owner if owner is not None and owner.shapedeform.is_bound else None
