# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender glue for Shape Deform.

Each submodule exposes a ``classes`` tuple; they are registered in the order
listed here and unregistered in reverse. The numerics live in the sibling,
Blender-free package and are imported relatively (``from ..solver import ...``).
"""

import bpy

from . import preferences

classes = (
    *preferences.classes,
)

register, unregister = bpy.utils.register_classes_factory(classes)
