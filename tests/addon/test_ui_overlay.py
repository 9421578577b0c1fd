# SPDX-License-Identifier: GPL-3.0-or-later
"""The sidebar panel is registered in its tab and the overlay's drawing data is right."""

import bpy
import numpy as np

import rig_checks as checks
from test_rig_mesh import grid


def test_panel_is_in_its_own_tab(addon):
    panel = bpy.types.SHAPEDEFORM_PT_panel
    assert (panel.bl_space_type, panel.bl_region_type, panel.bl_category) == ("VIEW_3D", "UI", "Shape Deform")


def test_overlay_draws_the_posed_graph_and_regions(addon):
    overlay = addon.shapedeform_addon.overlay
    obj = grid()
    bpy.ops.shapedeform.bind()
    assert overlay.drawing_data(obj) is None  # only when asked
    obj.shapedeform.show_overlay = True
    checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    handle = checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    handle.location.y += 0.25
    bpy.context.view_layer.update()
    data = overlay.drawing_data(obj)
    rig = addon.shapedeform_addon.rig.get(obj)
    assert data["edges"].shape == (2 * len(rig.graph.edges), 3) and data["edges"].dtype == np.float32
    assert len(data["regions"]) == len(rig.indices)
    world = checks.evaluated_mesh_points(obj) + np.array(obj.location)
    # The mesh is its own graph here: the overlay's points are the evaluated vertices.
    assert np.abs(data["edges"] - world[rig.graph.edges.ravel()]).max() < 1e-5
