# SPDX-License-Identifier: GPL-3.0-or-later
"""Text objects, rigged as they read: the outlines of their glyphs, holes and all.

The text stays text (its body, font and spacing editable): binding reads the glyphs' outlines
as Blender makes them for Object > Convert > Curve and builds the graph from them as for a
curve (:func:`.curve.prepare_splines`). The text reaches the Shape Deform modifier as its
tessellated mesh, which the modifier maps like any other points. Text typed after binding is
mapped by the part of the rest shape it lies on or nearest to; Unbind and Bind again to rig
the new glyphs themselves. Nothing of the text is written, so nothing needs giving back.
"""

import bpy

from ..errors import RigError
from . import curve


def prepare(obj, settings):
    """Read the glyphs' outlines and build the graph, changing nothing (see :mod:`.sources`)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    outlines = obj.to_curve(depsgraph, apply_modifiers=False)  # a temporary curve the object owns
    try:
        if not any(len(spline.bezier_points) or len(spline.points) for spline in outlines.splines):
            raise RigError(f"'{obj.name}' shows no glyphs: type some text (spaces alone have no outline)")
        return curve.prepare_splines(obj, outlines, settings)
    finally:
        obj.to_curve_clear()


def unbind(obj):
    """Nothing to give back: the text is never written (see :mod:`.sources`)."""
    return []


def restore_legacy(obj):
    """No older version rigged text objects (see :mod:`.sources`)."""
    return []


def selected(obj):
    """Refused: a text has no points to select (see :mod:`.sources`)."""
    raise RigError(f"'{obj.name}' is text, which has no points to select: add handles in Object Mode "
                   "(at the 3D cursor), or Ctrl+click the shape while dragging handles")
