# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender glue for Shape Deform.

Each submodule has a ``classes`` tuple and a ``register``/``unregister`` pair (most from
``bpy.utils.register_classes_factory``; properties and handlers also attach to Blender types
and handler lists). They are registered in the order listed here and unregistered in reverse.
The numerics live in the sibling, Blender-free package ``solver``, imported relatively.
"""

from . import bake, bake_source, cli, drag, handlers, keymaps, menus, operators, overlay, preferences, properties, ui

_modules = (preferences, properties, operators, drag, bake, bake_source, ui, menus, overlay, handlers, keymaps, cli)

classes = tuple(cls for module in _modules for cls in module.classes)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
