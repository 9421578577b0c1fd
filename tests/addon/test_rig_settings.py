# SPDX-License-Identifier: GPL-3.0-or-later
"""Rig settings reach the solver: Prevent Folds, the iteration budgets, a driven setting."""

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


def test_a_new_iteration_budget_poses_again_without_rebuilding(addon):
    """The budgets are not part of what the deformer is made of: changing one re-solves with the
    same deformer (rebuilding it refactorises and solves the coarse copy again)."""
    rig = addon.shapedeform_addon.rig
    obj, _, moved = rig_with_two_handles()
    moved.location.z += 0.6
    moved.rotation_euler.y += 0.8
    bpy.context.view_layer.update()
    deformer = rig.get(obj).deformer
    before = rig.pose(obj).posed.copy()
    obj.shapedeform.render_iterations = 1
    assert rig.get(obj).deformer is deformer
    assert np.abs(rig.get(obj).posed - before).max() > 1e-6  # posed again, one iteration short


def test_a_driven_setting_reposes_when_its_driver_changes(addon, quiet):
    """A setting driven by a control's custom property: changing the control solves the pose
    again, as editing the setting does (the settings' own update callbacks never run for a
    driven value, and the pose stayed the old value's until the next frame change)."""
    import rig_checks as checks

    obj, _, moved = rig_with_two_handles()
    moved.location.y += 0.6
    moved.rotation_euler.z += 1.0
    control = bpy.data.objects.new("Control", None)
    bpy.context.scene.collection.objects.link(control)
    control["detail"] = 0.0
    driver = obj.driver_add("shapedeform.weight_laplacian").driver
    variable = driver.variables.new()
    variable.name, variable.targets[0].id, variable.targets[0].data_path = "detail", control, '["detail"]'
    driver.expression = "1 + 8 * detail"
    bpy.context.view_layer.update()
    before = checks.evaluated_mesh_points(obj).copy()

    control["detail"] = 1.0
    control.update_tag()
    bpy.context.view_layer.update()
    assert obj.shapedeform.weight_laplacian == 9.0
    driven = checks.evaluated_mesh_points(obj).copy()
    assert np.abs(driven - before).max() > 1e-3
    obj.driver_remove("shapedeform.weight_laplacian")
    obj.shapedeform.weight_laplacian = 9.0  # the same value, set by hand
    bpy.context.view_layer.update()
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), driven, atol=1e-6)


def test_weights_that_leave_points_undecided_name_the_weight_that_would_decide_them(addon):
    """A grid's corners are in the curve term only: with Boundary Detail at 0 the status asks
    for it by its sidebar name (it asked for the two weights already given, by internal names)."""
    obj, _, right = rig_with_two_handles()
    assert obj.shapedeform.graph_mode == "AUTO"
    obj.shapedeform.weight_laplacian = 0.0
    right.location.y += 0.1
    bpy.context.view_layer.update()
    assert "give 'Boundary Detail' a positive weight" in obj.shapedeform.status
    obj.shapedeform.weight_laplacian = 1.0
    assert obj.shapedeform.status == ""
