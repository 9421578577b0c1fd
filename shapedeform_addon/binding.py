# SPDX-License-Identifier: GPL-3.0-or-later
"""Binding an object to a new rig, and unbinding it.

Binding computes everything first (so a refusal changes nothing), then adds the cage, the
handle collection and the Shape Deform modifier; the object's own shape is left as it is (an
image plane's quad is swapped for a cut-out of its picture, kept and given back on unbind; a
mesh in several islands gets its vertices' islands, removed on unbind; a curve whose path
nothing rides has its Path Animation turned off, turned on again on unbind). Binding turns its
scenes' Lock Interface on where it was off, turned off again by the unbind that leaves a scene
no rig. Unbinding releases the duplicates that follow the rig first.
"""

import bpy

from ..solver.wording import by_count
from . import bake, duplicates, handles, rig, rig_format, sources
from .errors import RigError


# Modifiers that add geometry away from the object's own (a mirrored half, array copies); a
# Geometry Nodes modifier may too.
GENERATING = {"MIRROR", "ARRAY", "SCREW", "BOOLEAN", "GREASE_PENCIL_MIRROR", "GREASE_PENCIL_ARRAY"}
# Modifiers that bend the whole shape away from its data (a rope bent along a path). Not an
# Armature's: a skeleton in its rest pose bends nothing, and applying it would undo the rig.
BENDING = {"CURVE", "LATTICE", "SIMPLE_DEFORM", "MESH_DEFORM", "SURFACE_DEFORM", "GREASE_PENCIL_LATTICE"}


def refusal(obj):
    """Why ``obj`` cannot be bound, judged without reading its geometry ("" when it may be).

    Cheap enough for an operator's poll: the interface greys Bind out with this as its tooltip.
    """
    if obj is None:
        return "No active object to rig"
    settings = obj.shapedeform
    if rig_format.is_follower(obj):
        owner = settings.cage.shapedeform.rig
        return f"'{obj.name}' follows the rig of '{owner.name}': unbind it first to give it its own"
    if settings.is_bound and settings.cage is None and not rig_format.is_legacy(obj):
        return rig.lost_cage(obj)
    if settings.is_bound:
        return f"'{obj.name}' is already bound"
    if settings.rig is not None:
        return f"'{obj.name}' is part of the rig of '{settings.rig.name}'"
    try:
        rig_format.require_posable(obj, "bind it")  # Blender drops edits of linked data on saving
        sources.kind_of(obj)
    except RigError as err:
        return str(err)
    return ""


def bind(obj):
    """Rig ``obj``; returns its :class:`rig.Rig`, advice for the user ("" when none), and the
    scenes whose Render > Lock Interface it turned on (frame handlers pose rigs during renders).

    Raises
    ------
    RigError
        The object cannot be rigged; the message says why and nothing was changed.
    """
    reason = refusal(obj)
    if reason:
        raise RigError(reason)
    settings = obj.shapedeform
    kind = sources.kind_of(obj)
    prepared = sources.module_for(obj).prepare(obj, settings)
    copied = rig_format.modifiers_of(obj)
    notes = [prepared.advice] if prepared.advice else []
    if copied:
        notes.append("removed the Shape Deform modifier copied from another rig")
    # A Geometry Nodes modifier of the user's may add geometry too (QA: a copy made by one was
    # rigged without a word, where Mirror's was told).
    adding = [m.name for m in obj.modifiers if (m.type in GENERATING or m.type == "NODES" and m not in copied)
              and (m.show_viewport or m.show_render)]
    if adding:
        # The rig is built from the object's own data; the rig's modifier comes after these.
        notes.append(f"the rig was built without what {', '.join(map(repr, adding))} add"
                     f"{by_count(len(adding), 's', '')}: their copies follow the nearest bound part; "
                     "apply them before binding to rig the whole shape")
    bending = [m.name for m in obj.modifiers if m.type in BENDING and (m.show_viewport or m.show_render)
               and getattr(m, "object", True) is not None and getattr(m, "is_bound", True)]  # idle ones bend nothing
    if bending:  # QA: a drag of a rope bent by a Curve modifier moved its end 3.4 times as far, elsewhere
        notes.append(f"the rig was built from the shape before {', '.join(map(repr, bending))} bend"
                     f"{by_count(len(bending), 's', '')} it, so handles pull the shape as it was: apply "
                     f"{by_count(len(bending), 'it', 'them')} before binding to rig the shape you see")
    prepared.advice = "; ".join(notes)
    prepared.commit(obj)
    rig_format.store_graph(settings, prepared.plane, prepared.graph)
    settings.cage = rig_format.make_cage(obj, prepared.plane, prepared.graph, handles.collection(obj), prepared.islands)
    # A deformer modifier copied from another rig (Copy Modifiers) would keep posing the object
    # with that rig's cage before this one's.
    for modifier in copied:
        obj.modifiers.remove(modifier)
    rig_format.add_modifier(obj, settings.cage, prepared.modifier_inputs)
    settings.kind = kind
    settings.is_bound = True
    settings.status = ""
    locked = [scene for scene in obj.users_scene if rig_format.lock_interface(scene)]
    rig.forget(obj)
    rig_format.forget_bound()
    return rig.get(obj), prepared.advice, locked


def unbind(obj):
    """Remove the rig: modifier, cage, bake, handles; the object's data is as it was.

    The duplicates following the rig stop following it first, as each would on its own. A
    follower (a duplicate of a rig's owner) gives up only its modifier and copied settings
    (an image plane gets its quad back); the owner's rig is untouched. What Bind changed on data
    that several objects share is given back by the last rig of it to go. A rig made by an
    older version, which wrote poses into the object's data, gets its rest shape back from what
    that version saved. A scene left with no rig gets back the Lock Interface Bind took.

    Returns
    -------
    list of str
        What could not be given back, as phrases for a message (empty when all was).

    Raises
    ------
    RigError
        ``obj`` is not bound, or its rig is a library's; nothing was changed.
    """
    settings = obj.shapedeform
    if not settings.is_bound:
        raise RigError(f"'{obj.name}' is not bound")
    rig_format.require_local(obj, "unbind it")
    # Only a rig made by an older version has rest points to give back. A modern rig without a
    # cage (a duplicate whose rig's owner an earlier version unbound, or a cage deleted by hand)
    # never wrote the object's data: there is nothing to restore.
    legacy = rig_format.is_legacy(obj)
    if rig_format.is_follower(obj):
        return duplicates.release_follower(obj)
    source = sources.unbinding_module(obj)
    # Followers first: released, they no longer count as rigs of data they share with it.
    lost = duplicates.release_followers(obj)
    if settings.cage is None:
        lost += (source.restore_legacy(obj) if legacy else []) + source.unbind(obj)
    else:
        bake.clear(obj)
        lost += source.unbind(obj)  # while the cage is there: it tells what transform was applied
        cage = settings.cage
        mesh = cage.data
        for orphan in duplicates.follower_cages(obj):  # of deleted duplicates (removed when the file is saved)
            bpy.data.objects.remove(orphan)
        bpy.data.objects.remove(cage)
        if mesh.users == 0:
            bpy.data.meshes.remove(mesh)
    for modifier in rig_format.modifiers_of(obj):  # after the source's unbind, which may ask whether it was applied
        obj.modifiers.remove(modifier)
    rig_format.forget(obj)
    handles.remove_all(obj)
    rig.forget(obj)
    rig_format.forget_bound()
    for scene in bpy.data.scenes:  # the one it is in, or any it was bound in and moved out of
        rig_format.unlock_interface(scene)
    return lost
