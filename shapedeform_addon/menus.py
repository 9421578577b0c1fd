# SPDX-License-Identifier: GPL-3.0-or-later
"""Menu entries, so every operator is where Blender users look for it (and F3 finds it).

Object > Shape Deform holds them all; Object > Animation has the bake beside Blender's own
Bake Action; the Edit Mode menus of meshes, curves and grease pencil add a handle at each
selected point. Operators that do not apply are greyed out with their poll's reason.
"""

import bpy

from .ui import KIND_ICONS


class SHAPEDEFORM_MT_object(bpy.types.Menu):
    """Shape Deform: rig, pin, pose and bake 2D shapes"""

    bl_idname = "SHAPEDEFORM_MT_object"
    bl_label = "Shape Deform"

    def draw(self, context):
        layout = self.layout
        layout.operator("shapedeform.bind", icon="MOD_MESHDEFORM")
        layout.operator("shapedeform.unbind", icon="X")
        layout.separator()
        layout.operator("shapedeform.add_handle", text="Add Handle", icon=KIND_ICONS["POSITION"])
        layout.operator("shapedeform.add_handle", text="Add Overlap Pin", icon=KIND_ICONS["OVERLAP"]).kind = "OVERLAP"
        layout.operator("shapedeform.add_handle", text="Add Starch Pin", icon=KIND_ICONS["STARCH"]).kind = "STARCH"
        layout.operator("shapedeform.remove_handle", icon="REMOVE")
        layout.operator("shapedeform.make_handles_editable", icon="LIBRARY_DATA_OVERRIDE")
        layout.separator()
        layout.operator("shapedeform.drag", icon="MOUSE_LMB_DRAG")
        layout.separator()
        layout.operator("shapedeform.bake", icon="REC")
        layout.operator("shapedeform.clear_bake", icon="TRASH")


def _object_menu(self, context):
    self.layout.separator()
    self.layout.menu(SHAPEDEFORM_MT_object.bl_idname)


def _animation_menu(self, context):
    self.layout.separator()
    self.layout.operator("shapedeform.bake", text="Bake Shape Deform")


def _edit_menu(self, context):
    self.layout.separator()
    self.layout.operator("shapedeform.add_handle", text="Add Shape Deform Handle", icon=KIND_ICONS["POSITION"])


# (Blender menu, what we add to it). Edit menus are looked up by name: they differ by version.
ENTRIES = (
    ("VIEW3D_MT_object", _object_menu),
    ("VIEW3D_MT_object_animation", _animation_menu),
    ("VIEW3D_MT_edit_mesh", _edit_menu),
    ("VIEW3D_MT_edit_curve", _edit_menu),
    ("VIEW3D_MT_edit_greasepencil", _edit_menu),
)

classes = (SHAPEDEFORM_MT_object,)

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    _register_classes()
    for name, draw in ENTRIES:
        menu = getattr(bpy.types, name, None)
        if menu is not None:
            menu.append(draw)


def unregister():
    for name, draw in ENTRIES:
        menu = getattr(bpy.types, name, None)
        if menu is not None:
            menu.remove(draw)
    _unregister_classes()
