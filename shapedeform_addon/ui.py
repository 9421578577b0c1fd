# SPDX-License-Identifier: GPL-3.0-or-later
"""The sidebar panel (3D viewport, tab "Shape Deform")."""

import bpy


class SHAPEDEFORM_PT_panel(bpy.types.Panel):
    bl_label = "Shape Deform"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Shape Deform"

    def draw(self, context):
        layout = self.layout
        obj = context.active_object
        if obj is None:
            layout.label(text="No active object")
            return
        if obj.shapedeform.rig is not None:
            obj = obj.shapedeform.rig
        settings = obj.shapedeform
        if not settings.is_bound:
            layout.prop(settings, "graph_mode")
            layout.prop(settings, "density")
            layout.prop(settings, "layers")
            layout.operator("shapedeform.bind")
            return
        layout.operator("shapedeform.unbind")


classes = (SHAPEDEFORM_PT_panel,)

register, unregister = bpy.utils.register_classes_factory(classes)
