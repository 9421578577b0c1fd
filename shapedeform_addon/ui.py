# SPDX-License-Identifier: GPL-3.0-or-later
"""The sidebar panel (3D viewport, tab "Shape Deform")."""

import bpy

from . import bake, bake_source, compat, handles, keymaps, nodes
from .rig_format import active_rig, is_baked, is_follower, modifiers_of, present
from .sources import grease_pencil


KIND_ICONS = {"POSITION": "EMPTY_DATA", "OVERLAP": "SELECT_SUBTRACT", "STARCH": "MOD_SOLIDIFY"}


class SHAPEDEFORM_UL_handles(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0):
        if not present(item.object, data.handle_collection):  # deleted in the viewport: the rig no longer uses it
            layout.label(text=f"{item.object.name if item.object else ''} (deleted)", icon="ERROR")
            return
        kind = item.object.shapedeform.pin_kind
        row = layout.row()
        row.prop(item.object, "name", text="", emboss=False, icon=KIND_ICONS[kind])
        row.label(text=kind.title())


class SHAPEDEFORM_PT_panel(bpy.types.Panel):
    """Bind, or the rig's handles and pins; sub-panels hold the solver's settings and animation."""

    bl_label = "Shape Deform"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Shape Deform"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        active = context.active_object
        if active is None:
            layout.label(text="No active object")
            return
        if is_follower(active):
            layout.label(text=f"Follows the rig of '{active.shapedeform.cage.shapedeform.rig.name}'", icon="LINKED")
            layout.operator("shapedeform.unbind", text="Stop Following", icon="X")
            return
        obj = active_rig(context) or active
        settings = obj.shapedeform
        if not settings.is_bound:
            col = layout.column()
            col.prop(settings, "graph_mode")
            col.prop(settings, "density")
            if obj.type == "GREASEPENCIL":
                col.prop(settings, "layers")
                col.prop(settings, "layers_apart")
            col.operator("shapedeform.bind", icon="MOD_MESHDEFORM")
            return
        layout.operator("shapedeform.unbind", icon="X")
        if obj.name not in context.scene.objects:
            # Deleting a rigged object leaves its handles (as deleting a parent leaves its children).
            layout.label(text=f"'{obj.name}' is not in this scene (deleted?): Unbind removes its rig", icon="INFO")
        if settings.status:
            layout.label(text=settings.status, icon="ERROR")
        if active is not obj and active.type == "EMPTY" and not handles.listed(obj, active):
            # A copy of a handle or pin (Shift+D) names the rig but is in no list of it.
            layout.label(text=f"'{active.name}' is not one of the rig's handles (a copy?): it moves nothing",
                         icon="INFO")
        if handles.locked_by_override(obj):
            layout.operator("shapedeform.make_handles_editable", icon="LIBRARY_DATA_OVERRIDE")
        _draw_handles(layout, settings)
        layout.prop(settings, "region_size")
        _draw_modifier_inputs(layout, obj)
        layout.prop(settings, "show_overlay")


class _RigSubPanel:
    """A sub-panel shown while the active object belongs to a rig of its own."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Shape Deform"
    bl_parent_id = "SHAPEDEFORM_PT_panel"

    @classmethod
    def poll(cls, context):
        active = context.active_object
        return active is not None and not is_follower(active) and active_rig(context) is not None


class SHAPEDEFORM_PT_solver(_RigSubPanel, bpy.types.Panel):
    """What the rig minimises and how long it may take."""

    bl_label = "Solver"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        settings = active_rig(context).shapedeform
        layout = self.layout
        layout.use_property_split = True
        col = layout.column(align=True, heading="Energy Weights")
        col.prop(settings, "weight_laplacian")
        col.prop(settings, "weight_mvc")
        col.prop(settings, "weight_edge")
        col = layout.column(heading="Keep")
        col.prop(settings, "preserve_area")
        col.prop(settings, "prevent_flips")
        col = layout.column(align=True, heading="Iterations")
        col.prop(settings, "iterations")
        col.prop(settings, "render_iterations")


class SHAPEDEFORM_PT_animation(_RigSubPanel, bpy.types.Panel):
    """Posing with the mouse, and baking to keyframes."""

    bl_label = "Pose and Animate"

    def draw(self, context):
        obj = active_rig(context)
        col = self.layout.column(align=True)
        # The drag needs the viewport's own region, so it runs from its key, not a button here.
        col.label(text=f"Drag handles: {keymaps.shortcut('shapedeform.drag')} in the viewport", icon="MOUSE_LMB_DRAG")
        if not is_baked(obj):
            col.operator("shapedeform.bake", icon="REC")
            return
        frames = bake.baked_frames(obj)
        baked = f"Baked {bake.frames_text(*frames[:2])}" if frames is not None else "Baked"
        col.label(text=f"{baked}: the keyframes play, the rig waits", icon="KEYFRAME_HLT")
        if bake_source.is_out_of_date(obj):
            col.label(text="Out of date: handles or settings changed since the bake", icon="ERROR")
        outside = _outside_bake(context.scene, bake.played_frames(obj, context.scene))
        if outside:
            col.label(text=outside, icon="INFO")
        row = col.row(align=True)
        again = row.operator("shapedeform.bake", text="Bake Again", icon="REC")
        again.again = True  # each selected rig over its own bake's frames
        if frames is not None:  # the bake it replaces: a farm's full range, not the preview range on now
            again.frame_start, again.frame_end, again.step = frames
        row.operator("shapedeform.clear_bake", icon="TRASH")


def _outside_bake(scene, frames):
    """A line on the frames of ``scene``'s range outside ``frames`` (first, last), where a bake
    plays, which hold its nearest pose (the range grown after baking, the bake retimed); "" when
    none or unknown."""
    if frames is None:
        return ""
    start, end = scene.frame_start, scene.frame_end
    parts = ([bake.frames_text(start, min(frames[0] - 1, end))] if start < frames[0] else []) + \
        ([bake.frames_text(max(frames[1] + 1, start), end)] if end > frames[1] else [])
    return f"The scene's {' and '.join(parts)} hold the nearest baked pose" if parts else ""


def _draw_handles(layout, settings):
    """The handle list, its buttons, and the active pin's values."""
    layout.label(text="Handles")
    row = layout.row()
    row.template_list("SHAPEDEFORM_UL_handles", "", settings, "handles", settings, "active_handle", rows=3)
    active = settings.handles[settings.active_handle].object if len(settings.handles) > settings.active_handle else None
    buttons = row.column(align=True)
    buttons.operator("shapedeform.add_handle", text="", icon="ADD")
    buttons.operator("shapedeform.add_handle", text="", icon=KIND_ICONS["OVERLAP"]).kind = "OVERLAP"
    buttons.operator("shapedeform.add_handle", text="", icon=KIND_ICONS["STARCH"]).kind = "STARCH"
    remove = buttons.operator("shapedeform.remove_handle", text="", icon="REMOVE")
    if active is not None:
        remove.handle = active.name  # the list's active item, as every list's "-" does
    elif len(settings.handles) > settings.active_handle:
        remove.deleted = settings.active_handle  # an entry whose handle is gone names no Empty
    if active is not None and active.shapedeform.pin_kind != "POSITION":
        col = layout.column(align=True)
        col.label(text=f"{active.shapedeform.pin_kind.title()} Pin '{active.name}'")
        col.prop(active.shapedeform, "in_front" if active.shapedeform.pin_kind == "OVERLAP" else "stiffness")
        col.prop(active.shapedeform, "extent")


def _draw_modifier_inputs(layout, obj):
    """The deformer modifier's own options that matter for this kind of object."""
    modifiers = modifiers_of(obj)  # only those with the extension's group
    if not modifiers:
        return
    modifier = modifiers[0]
    ids = nodes.input_identifiers(modifier.node_group)
    # Refine cuts the faces a mesh, a filled curve or a text reaches its modifier with.
    name = nodes.ORDER_INPUT if obj.type == "GREASEPENCIL" else nodes.REFINE_INPUT
    if name not in ids:
        return
    layout.prop(*compat.modifier_input_property(modifier, ids[name]), text=name)
    if name == nodes.ORDER_INPUT:
        losses = grease_pencil.stroke_order_losses(obj)
        if losses:
            on = compat.modifier_input(modifier, ids[name])
            layout.label(text=("Drops " if on else "Would drop ") + "; ".join(losses) + " while a pose folds",
                         icon="ERROR" if on else "INFO")


classes = (SHAPEDEFORM_UL_handles, SHAPEDEFORM_PT_panel, SHAPEDEFORM_PT_solver, SHAPEDEFORM_PT_animation)

register, unregister = bpy.utils.register_classes_factory(classes)
