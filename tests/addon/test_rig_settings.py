# SPDX-License-Identifier: GPL-3.0-or-later
"""Rig settings reach the solver: Prevent Folds."""

import bpy
import numpy as np

from test_rig_mesh import rig_with_two_handles


def test_prevent_folds_reaches_the_deformer_and_reposes(addon):
    rig = addon.shapedeform_addon.rig
    obj, _, _ = rig_with_two_handles()
    assert rig.get(obj).deformer.prevent_flips is True  # on by default
    obj.shapedeform.prevent_flips = False
    bpy.context.view_layer.update()
    assert rig.get(obj).deformer.prevent_flips is False


def test_viewport_and_render_iterations(addon):
    """Working in the viewport uses the Viewport budget; baking, rendering and Blender without
    a window use the Render one (headless here, so that is the default)."""
    rig = addon.shapedeform_addon.rig
    obj, _, moved = rig_with_two_handles()
    moved.location.z += 0.6
    moved.rotation_euler.y += 0.8
    obj.shapedeform.iterations = 1
    obj.shapedeform.render_iterations = 40
    bpy.context.view_layer.update()
    assert rig.final_quality()
    default = rig.pose(obj).posed.copy()
    viewport = rig.pose(obj, final=False).posed.copy()
    render = rig.pose(obj, final=True).posed.copy()
    deformer = rig.get(obj).deformer
    assert np.array_equal(default, render)
    assert np.abs(viewport - render).max() > 1e-6  # one iteration is visibly short of it
    targets = render[deformer.handles]
    converged = deformer.solve(targets, max_iterations=40).positions
    assert np.array_equal(render, converged)
