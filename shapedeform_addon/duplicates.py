# SPDX-License-Identifier: GPL-3.0-or-later
"""Duplicates of a rig's owner: a rig of their own, or followers of the rig.

Duplicated alone (Shift+D, Alt+D), a rigged object *follows* its rig: it shows the rig's pose
through a cage object of its own that shares the rig's cage mesh (:func:`follow`). Duplicated
together with handles of its rig, as an armature duplicated with its mesh, it gets a rig of its
own (:func:`adopt_duplicated`). :func:`settle_duplicate` decides, for a duplicate just made or
found in a file; unbinding the owner releases its followers first (:func:`release_followers`).
"""

import bpy

from . import handles, nodes, rig_format, sources
from .sources import image_plane


def adopt_duplicated(obj):
    """Give a duplicate that was made together with handles of its rig a rig of its own, as
    duplicating an armature with its mesh gives the copy its own armature; True when it did.

    Duplicating objects together points the copies' references at each other: the copy's
    handle list then names the copied Empties, whose rig is the copy. Those become its
    handles; it gets its own cage (a copy of the rig's, pose and bake included, the bake's keys
    in an action of its own: ``rig_format.copy_cage_mesh``) and its own handle collection, and
    its list drops the handles that stayed with the original.

    Pins alone pull nothing, and a rig of their own would snap the copy to its rest shape:
    duplicated without a handle, the copy follows the rig, and the copied pins are copies of
    the rig's pins, as pins duplicated alone are (:func:`.handles.listed` names none of them).
    """
    settings = obj.shapedeform
    own = [item.object for item in settings.handles if handles.owns(obj, item.object)]
    if not own:
        return False
    if all(empty.shapedeform.pin_kind != "POSITION" for empty in own):
        for empty in own:
            empty.shapedeform.rig = settings.cage.shapedeform.rig
        return False
    shared = settings.cage
    cage = _cage_for(obj, shared, shared.data)
    cage.data = rig_format.copy_cage_mesh(shared.data, cage)
    cage.shapedeform.rig = obj
    settings.handle_collection = None  # the original's: this rig gets its own
    home = handles.collection(obj)
    home.objects.link(cage)
    for empty in own:
        for other in empty.users_collection:
            other.objects.unlink(empty)
        home.objects.link(empty)
        if empty.parent == shared:  # a pin rides on the cage
            empty.parent = cage
    for i in reversed(range(len(settings.handles))):
        if not handles.owns(obj, settings.handles[i].object):
            settings.handles.remove(i)
    settings.cage = cage
    handles.set_active(settings, min(settings.active_handle, len(settings.handles) - 1))
    rig_format.point_inputs(obj, {nodes.CAGE_INPUT: cage})
    number_islands_apart(obj)
    return True


def _cage_for(obj, shared, mesh):
    """A copy of the cage object ``shared`` with ``mesh``, placed relative to ``obj`` as
    ``shared`` is to its owner (parented, or with a curve's path animation following it)."""
    cage = shared.copy()
    cage.data = mesh
    if shared.parent is not None:
        cage.parent = obj  # the parent inverse and own transform are copied with it
    for constraint in cage.constraints:  # a curve with path animation: the cage copies its transform
        if getattr(constraint, "target", None) is not None:
            constraint.target = obj
    return cage


def follow(obj):
    """Have a duplicate that follows a rig read it through a cage object of its own; True when
    something changed.

    The follower's cage shares the rig's cage mesh, so it shows every pose and bake, and is its
    child as the rig's cage is the owner's: the modifier maps the cage into the follower's space
    with the follower's own matrices, so Apply Transform on either object (which keeps a
    child's world place by changing the child's transform) keeps both where they are. Through
    the owner's cage, a duplicate read the rig in the owner's data space, and jumped when either
    data was transformed. A follower made by an older version gets its cage here too.
    """
    if any(nodes.LEGACY_OWNER_INPUT in nodes.input_identifiers(m.node_group) for m in rig_format.modifiers_of(obj)):
        # A linked library's group from before followers had cages of their own: it reads the
        # rig's cage in the space its Owner input names, which duplicating pointed at the copy.
        # (A group of any later version, older than this one or not, takes the cage below.)
        return rig_format.point_inputs(obj, {nodes.LEGACY_OWNER_INPUT: obj.shapedeform.cage.shapedeform.rig})
    cage = obj.shapedeform.cage
    followed = _rig_followed(obj)
    if followed != cage.shapedeform.rig:  # duplicated with a rig's owner and handles: follow the copy
        settle_duplicate(followed)  # the copied owner gets its own cage first
        cage = followed.shapedeform.cage
    if not is_own_cage(obj, cage):  # the owner's or another follower's (just duplicated, or an older file's)
        cage = _cage_for(obj, cage, cage.data)
        cage.name = f"{obj.name} Cage"
        # In no collection: Blender evaluates it for the modifier that reads it, and when the
        # duplicate is deleted nothing uses it any more (so it is not saved).
        obj.shapedeform.cage = cage
    return rig_format.point_inputs(obj, {nodes.CAGE_INPUT: cage})


def is_own_cage(obj, cage):
    """Whether ``cage`` sits on ``obj`` (parented to it, or following it by constraint): the
    owner's cage on the owner, a follower's own cage on the follower."""
    return cage.parent == obj or any(getattr(c, "target", None) == obj for c in cage.constraints)


def _rig_followed(obj):
    """The owner of the rig a follower follows: its cage's, unless it was duplicated together
    with a rig's owner and handles (a whole set, as an armature duplicated with its meshes): its
    handle list then names the copied handles, whose rig it follows."""
    current = obj.shapedeform.cage.shapedeform.rig
    named = {item.object.shapedeform.rig for item in obj.shapedeform.handles if item.object is not None}
    copied = [rig for rig in named if rig not in (None, current) and rig.shapedeform.is_bound]
    return copied[0] if len(copied) == 1 else current


def follower_cages(obj):
    """The cage objects of duplicates that follow ``obj``'s rig (:func:`follow`)."""
    shared = obj.shapedeform.cage
    if shared is None:
        return []
    return [o for o in bpy.data.objects if o != shared and o.type == "MESH" and o.data == shared.data
            and o.shapedeform.rig == obj.original]


def settle_duplicate(obj, opened=False):
    """A duplicate of a rig's owner, made or found: a rig of its own where it was duplicated
    with handles of the rig (:func:`adopt_duplicated`), else a follower of the rig
    (:func:`follow`). Library data is left as the library has it. (Its callers then have the
    driver that keeps the handles evaluated fit what it became:
    ``rig_format.keep_handles_evaluated``.)

    An image plane's duplicate gets a quad of its own where it needs one when it was just made
    (or, ``opened``, when its file was opened): looking for the planes bound on a quad reads
    every object, too slow for every update of every follower."""
    if obj.library is None and rig_format.is_follower(obj):
        if not rig_format.modifiers_of(obj):  # converted (Keep Original), its modifier applied: frozen
            release_follower(obj)
            return
        settled = adopt_duplicated(obj) or follow(obj)
        if settled or opened:
            image_plane.own_quad(obj)
    elif obj.library is None and rig_format.is_owner(obj):
        own_cage_mesh(obj)


def own_cage_mesh(obj):
    """Give an owner's cage a mesh of its own when another owner's cage has it; True when it did.

    Appending a rigged character twice with Reuse Data (the Asset Browser's way for a user's
    library) gives the two cage objects one mesh: each copy would show whichever rig posed
    last, and a bake of one would play on both. The mesh names its cage
    (``rig_format.CAGE_STAMP``), so this is found without looking through the file.
    """
    cage = obj.shapedeform.cage
    mesh = cage.data
    if cage.library is not None or mesh is None or mesh.library is not None:
        return False
    stamped = mesh.get(rig_format.CAGE_STAMP)
    if stamped == cage:
        return False
    if (not isinstance(stamped, bpy.types.Object) or stamped.data != mesh or stamped.shapedeform.rig is None
            or stamped.shapedeform.rig.shapedeform.cage != stamped):
        mesh[rig_format.CAGE_STAMP] = cage  # not stamped yet (an older file), or a copy made for this cage
        return False
    followers = follower_cages(obj)
    mesh = rig_format.copy_cage_mesh(mesh, cage)
    for own in [cage, *followers]:
        own.data = mesh
    mesh[rig_format.CAGE_STAMP] = cage
    number_islands_apart(obj)
    return True


def number_islands_apart(obj, with_sharers=False):
    """Number the islands of owner ``obj``'s rig from a first number no other rig has: on its
    cage, on its mesh and on its followers' meshes (``rig_format.renumber_islands``). Where
    another rig reads those meshes (a mesh two rigs deform), nothing, as both read the numbers;
    with ``with_sharers``, those rigs too, by the same shift (review: an older version's numbers
    past ``ISLANDS_END`` stayed on a shared mesh). True when it did (no data is a library's)."""
    if obj.type != "MESH":
        return False
    group, meshes, todo = [], set(), [obj]
    while todo:  # the owners that read these meshes, and their followers' meshes
        owner = todo.pop()
        if owner in group:
            continue
        group.append(owner)
        mine = [owner, *followers(owner)]
        meshes |= {o.data for o in mine if o.type == "MESH"}
        readers = [o for o in rig_format.bound_objects() if o.data in meshes and o not in mine]
        if readers and not with_sharers:
            return False
        todo += [o for o in readers if rig_format.is_owner(o)]
    if any(o.library is not None for o in group) or any(mesh.library is not None for mesh in meshes):
        return False
    rig_format.renumber_islands(obj.shapedeform.cage.data, meshes | {o.shapedeform.cage.data for o in group[1:]})
    return True


# The list of bound objects that keep_islands_apart last checked: ``rig_format.bound_objects``
# makes a new one when objects come or go, and only then can two rigs number alike.
_checked = {"bound": None}


def keep_islands_apart():
    """Where two rigs of different meshes number their islands from the same first number,
    number the later one's apart (:func:`number_islands_apart`; a library's rig is left as it
    is, and the other one is numbered apart then). A rig numbered past ``ISLANDS_END`` (by an
    older version, where subdivision put points a number off) is numbered anew too.

    A character appended twice, or pasted (Ctrl+V appends from a file), comes with copies of
    its meshes whose numbers are those of the original: joining one copy into the other made
    the joined part's vertices move with the other rig's islands."""
    bound = rig_format.bound_objects()
    if bound is _checked["bound"]:
        return
    _checked["bound"] = bound
    numbered = {}
    for obj in bound:
        if not rig_format.is_owner(obj) or obj.type != "MESH":
            continue
        first = rig_format.first_island(obj.shapedeform.cage.data)
        if not first:  # numbered from 1 by an older version
            continue
        if first >= rig_format.ISLANDS_END and number_islands_apart(obj, with_sharers=True):  # an older version's
            first = rig_format.first_island(obj.shapedeform.cage.data)
        other = numbered.setdefault(first, obj)
        if other is obj or other.data == obj.data or number_islands_apart(obj):
            continue
        if number_islands_apart(other):
            numbered[first] = obj


def followers(obj):
    """The duplicates that follow owner ``obj``'s rig (:func:`follow`)."""
    return [o for o in bpy.data.objects if rig_format.is_follower(o) and o.shapedeform.cage.shapedeform.rig == obj]


def release_follower(obj):
    """Make a follower a plain object: its modifiers, its own cage and its copy of the rig's
    settings go, and its source gives back what Bind changed on its data (an image plane's
    quad, a copied mesh's islands), unless the data is shared with a rig that stays.

    Returns
    -------
    list of str
        What could not be given back, as phrases for a message (see ``sources``).
    """
    settings = obj.shapedeform
    # While its cage and modifier are there: they tell what transform was applied, and whether
    # it was converted (its pose its own then, kept).
    # Converted (Keep Original) to a type no rig is made on: new data, none of Bind's.
    lost = sources.unbinding_module(obj).unbind(obj)
    for modifier in rig_format.modifiers_of(obj):
        obj.modifiers.remove(modifier)
    if is_own_cage(obj, settings.cage):  # its own (follow), sharing the rig's mesh
        bpy.data.objects.remove(settings.cage)
    settings.handles.clear()
    settings.handle_collection = None
    rig_format.forget(obj)
    rig_format.keep_handles_evaluated(obj)  # unbound now: its driver goes
    return lost


def release_followers(obj):
    """Release every duplicate that follows owner ``obj``'s rig (:func:`release_follower`), as
    the rig goes; what could not be given back, as phrases naming the duplicate."""
    lost = []
    for follower in followers(obj):
        lost += [f"on '{follower.name}', {phrase}" for phrase in release_follower(follower)]
    return lost
