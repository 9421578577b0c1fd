# SPDX-License-Identifier: GPL-3.0-or-later
"""Shape Deform: handle-based 2D shape deformation for Blender.

The repository root is the extension package. Everything Blender-specific
lives in ``shapedeform_addon``; this file only hands its entry points on so
that Blender finds ``register``/``unregister`` at the package root.
"""

from .shapedeform_addon import register, unregister

__all__ = ("register", "unregister")
