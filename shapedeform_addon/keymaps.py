# SPDX-License-Identifier: GPL-3.0-or-later
"""Keyboard shortcuts: Ctrl+Shift+D in Object Mode starts dragging handles (``shapedeform.drag``).

They go into the add-on key configuration, so users can change them in the preferences, and are
all removed on unregister (an emptied key map is removed too, leaving nothing behind).
"""

import bpy

# (key map name, space type, operator, key, modifiers)
KEYS = (
    ("Object Mode", "EMPTY", "shapedeform.drag", "D", {"ctrl": True, "shift": True}),
)

_added = []


def shortcut(idname):
    """How the interface writes ``idname``'s key ("Ctrl Shift D"), or "" when it has none."""
    for _, _, bound, key, modifiers in KEYS:
        if bound == idname:
            held = [name.capitalize() for name in ("ctrl", "shift", "alt", "oskey") if modifiers.get(name)]
            return " ".join(held + [key])
    return ""

classes = ()


def register():
    keyconfig = bpy.context.window_manager.keyconfigs.addon
    if keyconfig is None:  # some background sessions have no add-on key configuration
        return
    for name, space, idname, key, modifiers in KEYS:
        keymap = keyconfig.keymaps.new(name=name, space_type=space)
        _added.append((keymap, keymap.keymap_items.new(idname, key, "PRESS", **modifiers)))


def unregister():
    keyconfig = bpy.context.window_manager.keyconfigs.addon
    for keymap, item in reversed(_added):
        keymap.keymap_items.remove(item)
        if keyconfig is not None and len(keymap.keymap_items) == 0:
            keyconfig.keymaps.remove(keymap)
    _added.clear()
