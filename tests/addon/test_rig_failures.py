# SPDX-License-Identifier: GPL-3.0-or-later
"""A failed update keeps the last good pose, says why, and never writes NaN."""

import math

import bpy
import pytest
import numpy as np

import rig_checks as checks
from test_rig_mesh import grid, rig_with_two_handles


def test_a_handle_moved_to_nan_keeps_the_last_pose_and_reports(addon):
    obj, _, handle = rig_with_two_handles()
    handle.location.y += 0.4
    bpy.context.view_layer.update()
    good = checks.evaluated_mesh_points(obj)
    assert obj.shapedeform.status == ""

    handle.location.x = math.nan  # a driver or script gone wrong
    bpy.context.view_layer.update()
    after = checks.evaluated_mesh_points(obj)
    assert np.all(np.isfinite(after))
    np.testing.assert_array_equal(after, good)
    assert obj.shapedeform.status == f"'{handle.name}': its transform is not a finite number"

    handle.location.x = 1.0  # fixed: the rig poses again and the message goes
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    assert np.all(np.isfinite(checks.evaluated_mesh_points(obj)))


def test_a_frame_a_headless_render_cannot_pose_is_told_in_its_log(addon, capfd):
    """A farm's Render Animation of a frame a rig cannot pose (a handle keyed to NaN) rendered
    the pose of the frame before and said nothing: the reason went into the owner's status,
    which no one reads headless (QA). The frame handler prints it with the frame."""
    obj, _, handle = rig_with_two_handles()
    handle.keyframe_insert("location", frame=1)
    handle.location.x = math.nan
    handle.keyframe_insert("location", frame=6)
    scene = bpy.context.scene
    scene.frame_set(1)
    capfd.readouterr()
    scene.frame_set(6)
    assert np.all(np.isfinite(checks.evaluated_mesh_points(obj)))
    said = capfd.readouterr().err
    assert f"Shape Deform: frame 6: '{handle.name}': its transform is not a finite number" in said
    scene.frame_set(1)
    assert "Shape Deform" not in capfd.readouterr().err


def test_an_object_scaled_to_zero_poses_bakes_and_comes_back(addon, quiet):
    """Keying the object's scale to 0 (popping it in and out) and flattening it across its
    plane: no traceback, no NaN, the bake runs through such frames and puts the scene back,
    and a flattened object keeps its rig (its shape's own axes are intact); a handle cannot be
    placed on an object with no extent, and says so. (What Blender's modifier stack makes of an
    object flattened to no thickness is Blender's: its relative transforms divide by zero.)"""
    obj, _, handle = rig_with_two_handles()
    scene = bpy.context.scene
    for frame, scale, y in ((1, 1.0, 0.0), (5, 0.0, 0.5), (10, 1.0, 0.8)):
        scene.frame_set(frame)
        obj.scale = (scale,) * 3
        obj.keyframe_insert("scale")
        handle.location.y = y
        handle.keyframe_insert("location")
    scene.frame_set(5)
    assert obj.shapedeform.status == ""
    assert np.all(np.isfinite(checks.evaluated_mesh_points(obj)))
    scene.frame_set(10)
    posed = checks.evaluated_mesh_points(obj).copy()

    scene.frame_set(3)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=10) == {"FINISHED"}
    assert scene.frame_current == 3
    scene.frame_set(10)
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), posed, atol=1e-5)
    assert bpy.ops.shapedeform.clear_bake() == {"FINISHED"}

    obj.animation_data_clear()
    obj.scale = (1.0, 1.0, 0.0)  # S Z 0 on a shape in the XY plane
    handle.location.y += 0.1
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    assert np.all(np.isfinite(checks.evaluated_mesh_points(obj)))
    checks.add_handle(obj, checks.world(obj, [0.0, 0.2, 0.0]))
    assert obj.shapedeform.status == ""

    obj.scale = (0.0, 0.0, 0.0)
    bpy.context.view_layer.update()
    with pytest.raises(RuntimeError, match="scaled to zero"):
        bpy.ops.shapedeform.add_handle(location=(0.0, 0.0, 0.0))


@pytest.mark.parametrize("axis", [0, 1])
def test_a_card_flip_through_zero_scale_keeps_the_pose(addon, axis):
    """Scaling the object to 0 along an axis of its plane (a card flip) collapses that axis and
    nothing else: the rig's pose is the same as at full scale (handles mapped through the
    owner's least-squares inverse all fell on one line, and the shape jumped by up to 3.6)."""
    obj, _, handle = rig_with_two_handles()
    handle.location.y += 0.5
    handle.rotation_euler.z += 0.4
    bpy.context.view_layer.update()

    def cage_points():
        cage = obj.shapedeform.cage.evaluated_get(bpy.context.evaluated_depsgraph_get())
        return np.array([v.co for v in cage.data.vertices])

    full = cage_points()
    for scale in (0.0, -1.0):
        obj.scale[axis] = scale
        bpy.context.view_layer.update()
        assert obj.shapedeform.status == ""
        np.testing.assert_allclose(cage_points(), full, atol=1e-5)


def test_applying_the_modifier_says_the_handles_no_longer_move_it_and_unbind_keeps_the_shape(addon, quiet):
    """Apply the Shape Deform modifier (or convert the object, which applies it): the posed
    shape becomes the object's own, the sidebar says the handles no longer move it (they did
    nothing, silently), and Unbind removes the rig and keeps the applied shape."""
    obj, _, handle = rig_with_two_handles()
    handle.location.y += 0.4
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(obj).copy()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.object.modifier_apply(modifier=obj.modifiers[0].name) == {"FINISHED"}
    handle.location.y += 0.2
    bpy.context.view_layer.update()
    assert "lost its Shape Deform modifier" in obj.shapedeform.status
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), posed, atol=1e-6)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert not obj.shapedeform.is_bound
    np.testing.assert_allclose(checks.mesh_points(obj), posed, atol=1e-6)
    assert not any(o.shapedeform.rig == obj for o in bpy.data.objects)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_a_handle_cannot_be_added_at_a_location_that_is_not_finite(addon, value):
    """NaN is refused, and so is an infinity (which Blender's float property clamps to float32's
    largest value: a handle there made every later solve non-finite)."""
    obj, _, _ = rig_with_two_handles()
    count = len(obj.shapedeform.handles)
    with pytest.raises(RuntimeError, match="not a finite point"):
        bpy.ops.shapedeform.add_handle(location=(value, 0.0, 0.0))
    assert len(obj.shapedeform.handles) == count


@pytest.mark.parametrize("how", ["removed", "edited"])
def test_a_cage_removed_or_edited_under_a_posed_rig_is_reported_and_refused_by_the_bake(addon, how, tmp_path,
                                                                                      capsys):
    """The rig was built and cached when its cage went (or lost a vertex): the next move says why
    in the status (it raised from the handler on every move and frame), and the command line's
    bake refuses it by name (a removed cage left it out: 'no rigs with handles to bake')."""
    obj, _, handle = rig_with_two_handles()
    handle.location.y += 0.2
    bpy.context.view_layer.update()
    cage = obj.shapedeform.cage
    if how == "removed":
        bpy.data.objects.remove(cage)
    else:
        cage.data.vertices.add(1)
    handle.location.y += 0.2
    bpy.context.view_layer.update()
    assert ("lost its cage" if how == "removed" else "was edited") in obj.shapedeform.status
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "broken.blend"))
    assert addon.shapedeform_addon.cli.main(["bake", "--frames", "1-2"]) == 1
    assert "'Grid'" in capsys.readouterr().err


def test_the_bake_refuses_a_rig_that_lost_its_modifier(addon):
    obj, _, handle = rig_with_two_handles()
    handle.keyframe_insert("location", frame=1)
    obj.modifiers.remove(addon.shapedeform_addon.rig_format.modifiers_of(obj)[0])
    with pytest.raises(addon.shapedeform_addon.errors.RigError, match="lost its Shape Deform modifier"):
        addon.shapedeform_addon.bake.bake_objects([obj], 1, 2)


@pytest.mark.parametrize("damage", ["handle offsets deleted", "pin point out of range"])
@pytest.mark.parametrize("damaged_first", [True, False])
def test_a_rig_whose_saved_data_is_damaged_says_so_and_the_others_still_pose(addon, damage, damaged_first, capfd):
    """Saved data damaged by hand (an ID property deleted or edited by a script) raised out of
    the update handler, which then posed no other rig, and left no status saying why."""
    rig_format = addon.shapedeform_addon.rig_format
    made = {}
    for name in ("Damaged", "Healthy") if damaged_first else ("Healthy", "Damaged"):
        obj = grid(name)
        made[name] = (obj, *checks.bind_with_handles(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]))
    damaged, _, hand = made["Damaged"]
    healthy, _, other_hand = made["Healthy"]
    if damage == "handle offsets deleted":
        del damaged.shapedeform.handles[1][rig_format.HANDLE_OFFSETS]
    else:
        checks.select_only(damaged)
        assert bpy.ops.shapedeform.add_handle(location=checks.world(damaged, [0.0, 0.0, 0.0]), kind="OVERLAP") \
            == {"FINISHED"}
        damaged.shapedeform.handles[-1][rig_format.PIN_POINT] = 10**6
    addon.shapedeform_addon.rig.forget()  # as an undo or a reopened file: rigs are read again
    kept = checks.evaluated_mesh_points(damaged).copy()
    rest = checks.evaluated_mesh_points(healthy).copy()
    capfd.readouterr()
    hand.location.y += 0.3
    other_hand.location.y += 0.3
    bpy.context.view_layer.update()
    assert healthy.shapedeform.status == ""
    assert (checks.evaluated_mesh_points(healthy)[:, 1] - rest[:, 1]).max() > 0.2  # it posed
    assert damaged.shapedeform.status.startswith("'Damaged' could not be posed (")
    assert damaged.shapedeform.status.endswith("else please report it")
    np.testing.assert_array_equal(checks.evaluated_mesh_points(damaged), kept)  # the last pose, no NaN
    out, err = capfd.readouterr()
    assert "Error in bpy.app.handlers" not in out + err  # what Blender prints when a handler raises
    assert "Traceback" in err  # the damage's own, printed for whoever looks into it
