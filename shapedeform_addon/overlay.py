# SPDX-License-Identifier: GPL-3.0-or-later
"""Viewport overlay: the graph's edges, each handle's region and each overlap pin's reach
(light where it brings the shape in front, dark where it sends it behind, as After Effects tints
its overlap pins), drawn with the gpu module.

:func:`drawing_data` computes what to draw and is testable headless; :func:`draw` only hands it
to the GPU, which has no context without a window.
"""

import bpy
import numpy as np

from ..solver.rigging import depth
from ..solver.rigging.plane import transform_points
from . import rig as rigs
from . import rig_format
from .errors import RigError

EDGE_COLOR = (0.2, 0.8, 1.0, 0.6)
REGION_COLOR = (1.0, 0.5, 0.1, 1.0)
REACH_OPACITY = 0.8
STARCH_COLOR = (0.3, 0.55, 1.0, 0.8)

_handle = None


def drawing_data(obj):
    """World-space geometry of ``obj``'s rig overlay, or None when there is nothing to draw.

    Returns
    -------
    dict or None
        ``edges``: (2k, 3) float32 line endpoints of the graph at its current pose;
        ``regions``: (m, 3) float32 graph points owned by handles;
        ``reach``: (r, 3) float32 graph points overlap and starch pins reach, and
        ``reach_colors``, (r, 4) float32: white for in front, black for behind, as opaque as
        the overlap pins' summed amount there (``REACH_OPACITY`` at 1 or more); then blue for
        starch, as opaque as its stiffness (full at 10).
    """
    if obj is None or not obj.shapedeform.is_bound or not obj.shapedeform.show_overlay:
        return None
    try:
        rig = rigs.as_shown(obj)
    except RigError:
        return None
    points = transform_points(rig_format.rig_space(obj), rig.shown)
    reached, colors = depth.reach_tints(rig.in_front, rig.overlap_reach, rig.starch, rig.starch_reach,
                                        REACH_OPACITY, STARCH_COLOR)
    return {"edges": points[rig.graph.edges.ravel()].astype(np.float32),
            "regions": points[rig.indices].astype(np.float32),
            "reach": points[reached].astype(np.float32),
            "reach_colors": colors}


def draw():
    """POST_VIEW callback of the 3D viewport."""
    import gpu
    from gpu_extras.batch import batch_for_shader

    obj = rig_format.owner_of(bpy.context.active_object)
    data = drawing_data(obj)
    if data is None:
        return
    shader = gpu.shader.from_builtin("UNIFORM_COLOR")
    gpu.state.blend_set("ALPHA")
    shader.uniform_float("color", EDGE_COLOR)
    batch_for_shader(shader, "LINES", {"pos": data["edges"]}).draw(shader)
    gpu.state.point_size_set(6.0)
    shader.uniform_float("color", REGION_COLOR)
    batch_for_shader(shader, "POINTS", {"pos": data["regions"]}).draw(shader)
    if len(data["reach"]):
        shader = gpu.shader.from_builtin("FLAT_COLOR")
        batch_for_shader(shader, "POINTS", {"pos": data["reach"], "color": data["reach_colors"]}).draw(shader)
    gpu.state.blend_set("NONE")


classes = ()


def register():
    global _handle
    _handle = bpy.types.SpaceView3D.draw_handler_add(draw, (), "WINDOW", "POST_VIEW")


def unregister():
    global _handle
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, "WINDOW")
        _handle = None
