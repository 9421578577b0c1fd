# SPDX-License-Identifier: GPL-3.0-or-later
"""Operators: bind, unbind, add and remove handles, make an override's handles editable.

Every operator refuses bad input with a message in the status bar and changes nothing; where the
context alone rules it out, its poll says why (the interface greys it out with that tooltip, and
a script's call raises RuntimeError with it). Each leaves the object in the mode it found it in
(where Blender lets it: a hidden object cannot enter Edit Mode again).
"""

from contextlib import contextmanager

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatVectorProperty, IntProperty, StringProperty

from ..solver.rigging.plane import affine_inverse, transform_points
from ..solver.wording import by_count
from . import binding, handles, rig, rig_format, sources
from .errors import RigError, poll_reason
from .properties import PIN_KINDS


class SHAPEDEFORM_OT_bind(bpy.types.Operator):
    """Rig the active object: find its plane, build its graph and cage, and add its Shape Deform modifier"""

    bl_idname = "shapedeform.bind"
    bl_label = "Bind"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_reason(cls, binding.refusal(context.active_object))

    def execute(self, context):
        obj = context.active_object
        try:
            with _in_object_mode(obj):
                bound, advice, locked = binding.bind(obj)
        except RigError as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        # Said because it changes how the interface behaves while rendering, beyond the object.
        lock = (f"; turned on Render > Lock Interface in {', '.join(repr(s.name) for s in locked)} (rigs pose "
                "during renders; off again when its last rig is unbound)") if locked else ""
        if advice:
            self.report({"WARNING"}, f"Bound '{obj.name}' ({bound.graph.n} graph points); {advice}{lock}")
        else:
            self.report({"INFO"}, f"Bound '{obj.name}': {bound.graph.n} graph points{lock}")
        return {"FINISHED"}


class SHAPEDEFORM_OT_unbind(bpy.types.Operator):
    """Remove the rig (modifier, cage, handles and bake; its duplicates stop following it); a duplicate that follows another object's rig only stops following it"""

    bl_idname = "shapedeform.unbind"
    bl_label = "Unbind"
    bl_options = {"REGISTER", "UNDO"}

    @staticmethod
    def _target(context):
        active = context.active_object
        # A duplicate that follows a rig stops following it; otherwise the rig the user means goes.
        return active if active is not None and rig_format.is_follower(active) else rig_format.active_rig(context)

    @classmethod
    def poll(cls, context):
        target = cls._target(context)
        return poll_reason(cls, "The active object is not bound" if target is None
                           else rig_format.local_refusal(target, "unbind it"))

    def execute(self, context):
        obj = self._target(context)
        if obj is None:
            self.report({"ERROR"}, "The active object is not bound")
            return {"CANCELLED"}
        owner = rig_format.owner_of(obj)
        try:
            with _in_object_mode(context.active_object):
                lost = binding.unbind(obj)
        except RigError as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        if lost:
            self.report({"WARNING"}, f"Unbound '{obj.name}', but could not give back {'; '.join(lost)}")
        elif owner is not None and owner != obj:
            self.report({"INFO"}, f"'{obj.name}' no longer follows the rig of '{owner.name}'")
        return {"FINISHED"}


class SHAPEDEFORM_OT_add_handle(bpy.types.Operator):
    """Add a handle at a location, at the 3D cursor (Object Mode), or one at each selected point (Edit Mode)"""

    bl_idname = "shapedeform.add_handle"
    bl_label = "Add Handle"
    bl_options = {"REGISTER", "UNDO"}

    # Not remembered between calls: a plain Add Handle after adding a pin adds a handle again.
    location: FloatVectorProperty(name="Location", subtype="TRANSLATION", size=3, options={"SKIP_SAVE"},
                                  description="World location of the handle (projected onto the shape's plane)")
    kind: EnumProperty(name="Kind", items=PIN_KINDS, default="POSITION", options={"SKIP_SAVE"},
                       description="A handle that moves the shape, or a pin that sets its depth or stiffness")

    @classmethod
    def poll(cls, context):
        owner = rig_format.active_rig(context)
        return poll_reason(cls, "Bind the object before adding handles" if owner is None
                           else rig_format.local_refusal(owner, "add handles"))

    def execute(self, context):
        active = context.active_object
        obj = rig_format.active_rig(context)
        if obj is None:
            self.report({"ERROR"}, "Bind the object before adding handles")
            return {"CANCELLED"}
        given = self.properties.is_property_set("location")
        at_selection = active.mode == "EDIT" and not given
        notes = []
        try:
            # Leaving Edit Mode writes the selection into the data.
            with _in_object_mode(active):
                locations, islands = self._locations(context, active, obj, given, at_selection)
                added = handles.add_all(obj, locations, kind=self.kind, on_rest=at_selection, notes=notes,
                                        islands=islands)
                rig.pose_safely(obj, context.evaluated_depsgraph_get())
        except RigError as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        view_layer = context.view_layer
        shown = [empty for empty in added if view_layer.objects.get(empty.name) == empty]
        if len(shown) < len(added):
            notes.append("the rig's handle collection is not in this view layer (excluded, or not in the "
                         "scene): the new handles work but are not shown")
        if active.mode == "OBJECT" and shown:  # as Blender adds objects: the new ones selected and active
            for other in context.selected_objects:
                other.select_set(False)
            for empty in shown:
                empty.select_set(True)
            view_layer.objects.active = shown[-1]
        if notes:
            self.report({"WARNING"}, "; ".join(notes))
        return {"FINISHED"}

    def _locations(self, context, active, obj, given, at_selection):
        """World locations (k, 3) of the handles to add, in the rig owner's space, and at a
        selection the island numbers (k,) of its points where the object keeps them (else None)."""
        if not at_selection:
            # As Blender adds things in Object Mode: at the 3D cursor (projected onto the plane).
            locations = np.array([self.location if given else context.scene.cursor.location], dtype=np.float64)
            if rig_format.is_follower(active):
                # On a duplicate that follows the rig: the same place on the owner.
                onto_owner = np.array(obj.matrix_world) @ affine_inverse(np.array(active.matrix_world))
                locations = transform_points(onto_owner, locations)
            return locations, None
        local, islands = sources.module_for(active).selected(active), sources.selected_islands(active)
        if len(local) == 0:
            raise RigError("Select points of the shape, or give a location")
        if self.kind != "POSITION":
            # One pin for the selection (a pin per point would add up: 63 of them lifted a hand
            # by more than the shape's size), on its point nearest the selection's centre.
            centre = [np.argmin(np.linalg.norm(local - local.mean(axis=0), axis=1))]
            local, islands = local[centre], None if islands is None else islands[centre]
        # Through the owner's matrix: a duplicate that follows its rig shares the owner's rest
        # shape in its own local coordinates, wherever the duplicate stands.
        return transform_points(obj.matrix_world, local), islands


class SHAPEDEFORM_OT_remove_handle(bpy.types.Operator):
    """Remove the selected handles"""

    bl_idname = "shapedeform.remove_handle"
    bl_label = "Remove Handle"
    bl_options = {"REGISTER", "UNDO"}

    handle: StringProperty(name="Handle", options={"SKIP_SAVE"},
                           description="Name of a handle of the active rig to remove (empty: the selected handles)")
    deleted: IntProperty(name="Deleted Entry", default=-1, options={"SKIP_SAVE", "HIDDEN"},
                         description="Index of an entry of the active rig's list whose handle was deleted, to remove")

    @classmethod
    def poll(cls, context):
        reachable = rig_format.active_rig(context) is not None or any(map(handles.rig_of, context.selected_objects))
        return poll_reason(cls, "" if reachable else "Select a rig or the handles to remove")

    def execute(self, context):
        if self.deleted >= 0:
            return self._remove_deleted_entry(rig_format.active_rig(context))
        if self.handle:
            # Looked up in the active rig's list: in a shot with library overrides a local and a
            # linked object may share the name, and a cage names its rig too.
            owner = rig_format.active_rig(context)
            listed = [item.object for item in owner.shapedeform.handles
                      if item.object is not None and item.object.name == self.handle] if owner else []
            selected = listed[:1]
        else:
            selected = [o for o in context.selected_objects if handles.rig_of(o) is not None]
        if not selected:
            self.report({"ERROR"}, f"'{self.handle}' is not a handle" if self.handle else "Select the handles to remove")
            return {"CANCELLED"}
        owners = {handles.rig_of(o) for o in selected}
        for owner in owners:
            try:
                rig_format.require_local(owner, "remove handles")
            except RigError as err:
                self.report({"ERROR"}, str(err))
                return {"CANCELLED"}
        removed = 0
        for owner in owners:
            removed += handles.remove(owner, set(selected), deleted_too=True)
            rig.pose_safely(owner, context.evaluated_depsgraph_get())
        if not removed:  # copies of handles (Shift+D): they name a rig, which does not list them
            self.report({"ERROR"}, f"{', '.join(repr(o.name) for o in selected)}: not in the handle list of "
                                   "its rig (a copy of a handle?); it moves nothing: delete it with X")
            return {"CANCELLED"}
        return {"FINISHED"}

    def _remove_deleted_entry(self, owner):
        """Drop the list's entry ``self.deleted`` of ``owner``'s rig, one whose handle is gone
        (what the list shows as deleted has no Empty to name)."""
        items = owner.shapedeform.handles if owner is not None else ()
        if self.deleted >= len(items) or items[self.deleted].object is not None:
            self.report({"ERROR"}, "No deleted handle there to remove")
            return {"CANCELLED"}
        try:
            rig_format.require_local(owner, "remove handles")
        except RigError as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        owner.shapedeform.handles.remove(self.deleted)
        handles.set_active(owner.shapedeform, min(self.deleted, len(items) - 1))
        return {"FINISHED"}


class SHAPEDEFORM_OT_make_handles_editable(bpy.types.Operator):
    """Make the handles of a library override's rig editable, to move and key them"""

    bl_idname = "shapedeform.make_handles_editable"
    bl_label = "Make Handles Editable"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        owner = rig_format.active_rig(context)
        return poll_reason(cls, "" if owner is not None and handles.locked_by_override(owner) else
                           "Only a library override's rig whose handles are not editable needs this")

    def execute(self, context):
        owner = rig_format.active_rig(context)
        locked = handles.locked_by_override(owner)
        for empty in locked:
            empty.override_library.is_system_override = False
        self.report({"INFO"}, f"Made {len(locked)} {by_count(len(locked), 'handle', 'handles')} of '{owner.name}' "
                              "editable")
        return {"FINISHED"}


@contextmanager
def _in_object_mode(obj):
    """Run the body in Object Mode (binding reads and swaps the object's data), then go back to
    the mode ``obj`` was in, whether the body worked or refused."""
    was = obj.mode if obj is not None else "OBJECT"
    if was != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    try:
        yield
    finally:
        if was != "OBJECT" and _still_active(obj):
            try:
                bpy.ops.object.mode_set(mode=was)
            except RuntimeError:
                pass  # Blender refuses some modes to a hidden object: it stays in Object Mode


def _still_active(obj):
    """``obj`` outlived the operator (unbinding deletes a cage) and is still the active object."""
    try:
        return bpy.context.view_layer.objects.active == obj
    except ReferenceError:
        return False


classes = (
    SHAPEDEFORM_OT_bind,
    SHAPEDEFORM_OT_unbind,
    SHAPEDEFORM_OT_add_handle,
    SHAPEDEFORM_OT_remove_handle,
    SHAPEDEFORM_OT_make_handles_editable,
)

register, unregister = bpy.utils.register_classes_factory(classes)
