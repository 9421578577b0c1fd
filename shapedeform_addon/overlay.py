# SPDX-License-Identifier: GPL-3.0-or-later
"""Viewport overlay: the graph's edges, each handle's region and each overlap pin's reach
(light where it brings the shape in front, dark where it sends it behind, as After Effects tints
its overlap pins), drawn with the gpu module.

:func:`drawing_data` computes what to draw and is testable headless; :func:`draw` only hands it
to the GPU, which has no context without a window.
"""

import bpy
import numpy as np

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
        the overlap pin's weight there times its amount (up to 1); then blue for starch.
    """
    if obj is None or not obj.shapedeform.is_bound or not obj.shapedeform.show_overlay:
        return None
    try:
        rig = rigs.get(obj)
    except RigError:
        return None
    points = transform_points(rig_format.rig_space(obj), rig.cage_points(rig.posed))
    strength = rig.in_front[:, None] * rig.overlap_reach  # (pins, n)
    reached = np.flatnonzero(np.abs(strength).sum(axis=0) > 0) if len(strength) else np.empty(0, np.int64)
    total = strength[:, reached].sum(axis=0) if len(strength) else np.empty(0)
    colors = np.zeros((len(reached), 4), np.float32)
    colors[:, :3] = (total > 0)[:, None]
    colors[:, 3] = np.minimum(np.abs(total), 1.0) * REACH_OPACITY
    # Starch pins: tinted blue, as opaque as their weight (a stiffness of 10 or more is full).
    stiff = rig.starch @ rig.starch_reach if len(rig.starch) else np.zeros(len(points))
    starched = np.flatnonzero(stiff > 0)
    starch_colors = np.tile(np.array(STARCH_COLOR, np.float32), (len(starched), 1))
    starch_colors[:, 3] *= np.minimum(stiff[starched] / 10.0, 1.0)
    return {"edges": points[rig.graph.edges.ravel()].astype(np.float32),
            "regions": points[rig.indices].astype(np.float32),
            "reach": np.concatenate([points[reached], points[starched]]).astype(np.float32),
            "reach_colors": np.concatenate([colors, starch_colors])}


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
