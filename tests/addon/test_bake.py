# SPDX-License-Identifier: GPL-3.0-or-later
"""Baking: the cage's motion as shape keys; every baked frame plays the live pose with the
extension disabled, for every kind; rebake replaces; the command line bakes a saved file;
animated poses do not depend on the frame shown before; a bake never adds or removes a
grease-pencil drawing and moves the animator's later ones too; a bake that cannot be written
changes nothing; outside the range every kind holds the nearest baked frame; the documented
Python entry point imports."""

from functools import partial
from types import SimpleNamespace
import re

import addon_utils
import bpy
import numpy as np
import pytest

from mathutils import Matrix, Vector

import renders
import rig_checks as checks
from extension_under_test import ADDON_MODULE
from test_rig_curve import curve_points, text_curve
from test_rig_grease_pencil import drawing_points
from test_handles_driver import duplicate
from test_rig_mesh import grid

FRAMES = range(1, 7)


def animate(handle, offset):
    """Key ``handle`` at frame 1 where it is and at frame 6 moved by ``offset`` (a turn too)."""
    handle.keyframe_insert("location", frame=1)
    handle.keyframe_insert("rotation_euler", frame=1)
    handle.location += Vector(offset)
    handle.rotation_euler.z += 0.3
    handle.keyframe_insert("location", frame=6)
    handle.keyframe_insert("rotation_euler", frame=6)


def rig(obj, first, second, offset):
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, first))
    animate(checks.add_handle(obj, checks.world(obj, second)), offset)


def cage_keys(obj):
    """Names of the shape keys on ``obj``'s cage (what a bake makes), [] when none."""
    keys = obj.shapedeform.cage.data.shape_keys
    return [block.name for block in keys.key_blocks] if keys is not None else []


def live(read):
    scene = bpy.context.scene
    result = {}
    for frame in FRAMES:
        scene.frame_set(frame)
        result[frame] = read().copy()
    return result


def assert_plays_without_extension(read, expected, frames=FRAMES):
    """Disable the extension, then every baked frame must show what the live rig showed."""
    addon_utils.disable(ADDON_MODULE, default_set=True)
    try:
        scene = bpy.context.scene
        for frame in reversed(frames):  # out of order, as a farm would
            scene.frame_set(frame)
            np.testing.assert_allclose(read(), expected[frame], atol=1e-5, err_msg=f"frame {frame}")
    finally:
        addon_utils.enable(ADDON_MODULE, default_set=True)


def test_mesh_bake_plays_without_the_extension_and_rebake_replaces(addon):
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    expected = live(lambda: checks.evaluated_mesh_points(obj))
    assert np.abs(expected[6] - expected[1]).max() > 0.3

    bake = addon.shapedeform_addon.bake
    assert bake.bake_objects([obj], 1, 6) == [obj]
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=6) == {"FINISHED"}  # again: replaces
    assert cage_keys(obj) == ["Basis"] + [bake.key_name(f) for f in FRAMES]
    assert obj.data.shape_keys is None  # the object's own data is left alone
    animation = obj.shapedeform.cage.data.shape_keys.animation_data
    from bpy_extras import anim_utils
    bag = anim_utils.action_get_channelbag_for_slot(animation.action, animation.action_slot)
    # One curve plays the keys in turn (an F-curve per key made each frame change search them all).
    assert [curve.data_path for curve in bag.fcurves] == ["eval_time"]
    times = addon.shapedeform_addon.rig_format.bake_key_times(len(FRAMES))
    assert [tuple(k.co) for k in bag.fcurves[0].keyframe_points] == list(zip(FRAMES, times))
    assert len(bpy.data.actions) == 2  # the handle's and the bake's
    assert_plays_without_extension(lambda: checks.evaluated_mesh_points(obj), expected)

    # A baked object plays its bake; clearing it gives the live rig back.
    assert bpy.ops.shapedeform.clear_bake() == {"FINISHED"}
    assert cage_keys(obj) == [] and "baked" not in obj.shapedeform
    assert len(bpy.data.actions) == 1  # the handle's
    bpy.context.scene.frame_set(4)
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), expected[4], atol=1e-5)


def test_curve_bake_plays_without_the_extension(addon):
    obj = text_curve("I")
    rest = np.concatenate([p[:, :3] for p in curve_points(obj)])
    low, high = rest[np.argmin(rest[:, 1])], rest[np.argmax(rest[:, 1])]
    rig(obj, low, high, (0.4, 0.0, 0.0))
    expected = live(lambda: checks.evaluated_vertices(obj))
    assert np.abs(expected[6] - expected[1]).max() > 0.2
    bake = addon.shapedeform_addon.bake
    bake.bake_objects([obj], 1, 6)
    bake.bake_objects([obj], 1, 6)
    assert len(cage_keys(obj)) == 1 + len(FRAMES)
    assert obj.data.animation_data is None  # nothing keyed on the curve itself
    assert_plays_without_extension(lambda: checks.evaluated_vertices(obj), expected)


def test_text_bake_plays_without_the_extension_and_the_text_stays_text(addon):
    bpy.ops.object.text_add()
    obj = bpy.context.active_object
    obj.data.body = "I"
    rest = checks.evaluated_vertices(obj)
    low, high = rest[np.argmin(rest[:, 1])], rest[np.argmax(rest[:, 1])]
    rig(obj, low, high, (0.4, 0.0, 0.0))
    expected = live(lambda: checks.evaluated_vertices(obj))
    assert np.abs(expected[6] - expected[1]).max() > 0.2
    addon.shapedeform_addon.bake.bake_objects([obj], 1, 6)
    assert len(cage_keys(obj)) == 1 + len(FRAMES)
    assert obj.type == "FONT" and obj.data.body == "I" and obj.data.animation_data is None
    assert_plays_without_extension(lambda: checks.evaluated_vertices(obj), expected)


def test_grease_pencil_bake_moves_every_drawing_and_adds_none(addon):
    """Issue 15, defect 7: the animator's later drawings follow the rig, live and baked."""
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    lines = obj.data.layers["Lines"]
    lines.frames.copy(1, 4)  # the animator's own drawing from frame 4 on, drawn a little apart
    later = lines.frames[-1].drawing
    flat = checks.drawing_points(later) + np.float32([0.0, 0.0, 0.05])
    later.attributes["position"].data.foreach_set("vector", flat.ravel())
    rest = drawing_points(obj, evaluated=False)
    rig(obj, rest[np.argmin(rest[:, 2])], rest[np.argmax(rest[:, 2])], (0.3, 0.0, 0.0))
    expected = live(lambda: drawing_points(obj))
    bpy.context.scene.frame_set(6)
    assert np.abs(checks.evaluated_drawing_points(obj, "Lines") - flat).max() > 0.2  # the later drawing moves
    before = frame_numbers(obj)
    bake = addon.shapedeform_addon.bake
    bake.bake_objects([obj], 1, 6)
    bake.bake_objects([obj], 1, 6)
    assert frame_numbers(obj) == before == {"Fills": [1], "Lines": [1, 4]}
    assert_plays_without_extension(lambda: drawing_points(obj), expected)
    assert bpy.ops.shapedeform.clear_bake() == {"FINISHED"}
    assert frame_numbers(obj) == before and cage_keys(obj) == []
    assert checks.drawing_points(later).tobytes() == flat.tobytes()  # never written


def test_bad_bake_requests_change_nothing(addon):
    obj = grid()
    bpy.ops.shapedeform.bind()
    bake = addon.shapedeform_addon.bake
    RigError = addon.shapedeform_addon.errors.RigError
    with pytest.raises(RigError, match="no handles"):
        bake.bake_objects([obj], 1, 5)
    checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="comes before"):
        bake.bake_objects([obj], 5, 1)
    with pytest.raises(ValueError, match="step"):
        bake.bake_objects([obj], 1, 5, step=0)
    # Cancelled half way: nothing written, the scene back on its frame.
    bpy.context.scene.frame_set(3)
    assert bake.bake_objects([obj], 1, 5, cancelled=lambda: True) is None
    assert cage_keys(obj) == [] and "baked" not in obj.shapedeform
    assert bpy.context.scene.frame_current == 3


def test_pose_at_a_frame_does_not_depend_on_the_frame_before(addon):
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.6, 0.0))
    scene = bpy.context.scene
    for frame in range(1, 5):  # played from frame 1
        scene.frame_set(frame)
    played = checks.evaluated_mesh_points(obj).copy()
    scene.frame_set(6)
    scene.frame_set(4)  # jumped to, from later
    jumped_back = checks.evaluated_mesh_points(obj).copy()
    rig_module = addon.shapedeform_addon.rig
    rig_module.forget()  # as a fresh render-farm process would start
    scene.frame_set(2)
    scene.frame_set(4)
    fresh = checks.evaluated_mesh_points(obj)
    assert np.abs(played - checks.mesh_points(obj)).max() > 0.1  # posed, by the modifier alone
    np.testing.assert_allclose(jumped_back, played, atol=1e-6)
    np.testing.assert_allclose(fresh, played, atol=1e-6)


def test_deleting_a_handle_by_hand_drops_it_quietly(addon):
    obj = grid()
    bpy.ops.shapedeform.bind()
    left = checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    right = checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    right.location.y += 0.3
    bpy.context.view_layer.update()
    for o in bpy.context.selected_objects:
        o.select_set(False)
    left.select_set(True)
    bpy.context.view_layer.objects.active = left
    assert bpy.ops.object.delete() == {"FINISHED"}
    right.location.y += 0.1
    bpy.context.view_layer.update()
    rig_module = addon.shapedeform_addon.rig
    assert rig_module.get(obj).handle_objects == [right]
    assert obj.shapedeform.status == ""
    # With one handle left the shape moves rigidly with it.
    posed = checks.evaluated_mesh_points(obj)
    rest = checks.mesh_points(obj)
    assert np.all(np.isfinite(posed))
    bpy.context.scene.frame_set(3)
    assert obj.shapedeform.status == ""


def test_command_line_bakes_a_saved_file(addon, tmp_path, capsys):
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    path = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    main = addon.shapedeform_addon.cli.main

    for bad, message in [([], "required"), (["bake", "--frames", "ten"], "not a frame range"),
                         (["bake", "--frames", "9-2"], "comes before"),
                         (["bake", "--objects", "Nobody"], "no object named 'Nobody'"),
                         (["bake", "--objects", "Nobody", "--objects", "Grid"], "no object named 'Nobody'"),  # both kept
                         (["bake", "--output", str(tmp_path / "missing" / "x.blend")], "does not exist"),
                         (["bake", "--output", ""], "--output is empty"),  # an unset farm variable
                         (["bake", "--output", str(tmp_path)], "is a folder"),
                         (["bake", "--frames", "1048570-1048580"], "run past Blender's"),
                         (["bake", "--frames", "1-3000000000"], "run past Blender's"),  # not 3e9 frames' memory
                         (["bake", "--frames", "99999999999999999999"], "frame 99999999999999999999 runs past Blender's"),
                         (["bake", "--view-layer", "Nobody"], "no view layer named 'Nobody'"),
                         (["bake", "--scene", "Nobody"], "no scene named 'Nobody'"),
                         (["bake", "--scene", ""], "no scene named ''"),  # an unset farm variable
                         (["frobnicate"], "invalid choice")]:
        assert main(bad) == 2, bad
        assert message in capsys.readouterr().err
    assert cage_keys(obj) == []  # nothing was baked by the refusals

    out = str(tmp_path / "baked.blend")
    handle = obj.shapedeform.handles[0].object.name  # stands for its rig, as in the Bake operator
    assert main(["bake", "--frames", "1-6", "--objects", handle, "--output", out]) == 0
    printed = capsys.readouterr().out
    assert "frame 6/6" in printed and "saved" in printed
    bpy.ops.wm.open_mainfile(filepath=out)
    assert cage_keys(bpy.data.objects["Grid"])[1:] == [f"sd_bake_{f:04d}" for f in FRAMES]
    bpy.ops.wm.open_mainfile(filepath=path)
    assert cage_keys(bpy.data.objects["Grid"]) == []  # --output left the shot as it was
    assert main(["bake", "--frames", "2-3"]) == 0  # every rig, saved in place
    bpy.ops.wm.open_mainfile(filepath=path)
    assert len(cage_keys(bpy.data.objects["Grid"])) == 3


def test_command_line_paths_negative_frames_and_rigs_whose_handles_were_deleted(addon, tmp_path):
    """``--output //name`` lands beside the opened file; ``--frames -2-1`` and ``-3--1`` (the
    documented forms) bake negative frames; a rig whose handles were deleted by hand (X keeps
    them as orphans the rig still points at) is left out instead of failing the whole bake."""
    grid().name = "Hero"
    rig(bpy.data.objects["Hero"], [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    extra = grid()
    extra.name = "Extra"
    bpy.context.view_layer.objects.active = extra
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    handle = checks.add_handle(extra, checks.world(extra, [0.0, 0.0, 0.0]))
    for o in bpy.context.selected_objects:
        o.select_set(False)
    handle.select_set(True)
    bpy.context.view_layer.objects.active = handle
    assert bpy.ops.object.delete() == {"FINISHED"}
    path = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    main = addon.shapedeform_addon.cli.main

    assert main(["bake", "--frames", "-2-1", "--output", "//baked.blend"]) == 0
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "baked.blend"))
    assert cage_keys(bpy.data.objects["Hero"])[1:] == [f"sd_bake_{f:04d}" for f in (-2, -1, 0, 1)]
    assert cage_keys(bpy.data.objects["Extra"]) == []
    bpy.ops.wm.open_mainfile(filepath=path)
    assert main(["bake", "--frames", "-3--1"]) == 0
    bpy.ops.wm.open_mainfile(filepath=path)
    assert cage_keys(bpy.data.objects["Hero"])[1:] == [f"sd_bake_{f:04d}" for f in (-3, -2, -1)]


def test_a_rig_left_out_of_the_view_layer_is_refused_or_baked_from_one_that_shows_it(addon, tmp_path, capsys):
    """A rig the baking view layer does not evaluate (excluded there, or its collection
    disabled in viewports) would bake stale handles: the bake refuses and names the view layer;
    the command line bakes it from another view layer that shows it."""
    scene = bpy.context.scene
    character = bpy.data.collections.new("Character")
    scene.collection.children.link(character)
    obj = grid()
    for collection in obj.users_collection:
        collection.objects.unlink(obj)
    character.objects.link(obj)
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    expected = live(lambda: checks.evaluated_mesh_points(obj))
    scene.view_layers.new("Render")
    bpy.context.view_layer.layer_collection.children["Character"].exclude = True
    bpy.context.view_layer.update()
    path = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)

    with pytest.raises(addon.shapedeform_addon.errors.RigError, match="not evaluated in the view layer"):
        addon.shapedeform_addon.bake.bake_objects([obj], 1, 6)
    main = addon.shapedeform_addon.cli.main
    assert main(["bake", "--frames", "1-6"]) == 1
    assert "not evaluated in the view layer 'ViewLayer'" in capsys.readouterr().err
    assert main(["bake", "--frames", "1-6", "--view-layer", "Render"]) == 0
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Grid"]
    assert len(cage_keys(obj)) == 1 + len(FRAMES)
    bpy.context.view_layer.layer_collection.children["Character"].exclude = False
    assert_plays_without_extension(lambda: checks.evaluated_mesh_points(obj), expected)


def test_a_bake_with_time_stretching_plays_as_the_live_rig(addon):
    """Time Stretching (frame_map_old / frame_map_new) remaps every F-curve at playback, the
    bake's keys too: each frame's pose is keyed at its stretched time, so the baked frames show
    what the live rig showed (keyed at the frame itself, they were stretched twice)."""
    scene = bpy.context.scene
    scene.render.frame_map_old, scene.render.frame_map_new = 100, 50
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    expected = live(lambda: checks.evaluated_mesh_points(obj))
    assert np.abs(expected[6] - expected[1]).max() > 0.1
    assert addon.shapedeform_addon.bake.bake_objects([obj], 1, 6) == [obj]
    assert_plays_without_extension(lambda: checks.evaluated_mesh_points(obj), expected)


def hat_on_a_head(by="COPY_LOCATION"):
    """Rig B, whose handle follows a point of rigged object A's deformed shape (a hat pinned to
    a head, here by Copy Location to A's vertex group, or with ``by`` 'ARMATURE' by an Armature
    constraint on a bone that copies it), and A; with B's live pose at each frame."""
    first = grid("A")
    rig(first, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.6, 0.0))
    second = grid("B")
    second.location.y += 2.0
    bpy.context.view_layer.update()
    bpy.context.view_layer.objects.active = second
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(second, checks.world(second, [-1.0, 0.0, 0.0]))
    pinned = checks.add_handle(second, checks.world(second, [1.0, 0.0, 0.0]))
    tip = int(np.argmax(checks.mesh_points(first)[:, 0]))
    first.vertex_groups.new(name="tip").add([tip], 1.0, "REPLACE")
    if by == "ARMATURE":
        target = pinned.constraints.new("ARMATURE").targets.new()
        target.target, target.subtarget = armature_following(first, "tip"), "Bone"
    else:
        follow = pinned.constraints.new("COPY_LOCATION")
        follow.target, follow.subtarget = first, "tip"
    scene = bpy.context.scene
    expected = {}
    for frame in FRAMES:
        scene.frame_set(frame)
        scene.frame_set(frame)  # twice: the second pass poses B from A's new shape
        expected[frame] = checks.evaluated_mesh_points(second).copy()
    assert np.abs(expected[6] - expected[1]).max() > 0.1
    return first, second, expected


def armature_following(obj=None, group=None):
    """An armature with bones 'Bone' (at the origin) and 'Other' (at x = 1), 'Bone' with Copy
    Location to ``obj``'s vertex ``group`` where given."""
    armature = bpy.data.objects.new("Armature", bpy.data.armatures.new("Armature"))
    bpy.context.scene.collection.objects.link(armature)
    bpy.context.view_layer.objects.active = armature
    bpy.ops.object.mode_set(mode="EDIT")
    for name, x in (("Bone", 0.0), ("Other", 1.0)):
        bone = armature.data.edit_bones.new(name)
        bone.head, bone.tail = (x, 0.0, 0.0), (x, 0.2, 0.0)
    bpy.ops.object.mode_set(mode="OBJECT")
    if obj is not None:
        copy = armature.pose.bones["Bone"].constraints.new("COPY_LOCATION")
        copy.target, copy.subtarget = obj, group
    bpy.context.view_layer.update()
    return armature


def test_a_rig_whose_handle_follows_another_rigs_shape_bakes_on_the_same_frame(addon):
    """Each baked frame of B is posed from A's pose at that frame (B was baked from A's pose
    at the frame before: one frame late)."""
    first, second, expected = hat_on_a_head()
    assert addon.shapedeform_addon.bake.bake_objects([first, second], 1, 6) == [first, second]
    assert_plays_without_extension(lambda: checks.evaluated_mesh_points(second), expected)


@pytest.mark.parametrize("by", ["COPY_LOCATION", "ARMATURE"])
def test_baking_only_the_rig_that_follows_another_live_rig_poses_that_rig_on_every_frame(addon, by):
    """The animator selects only the hat and bakes it: A stays live, and each baked frame of B
    is still posed from A's pose at that frame (B was baked against A's pose frozen at the
    bake's first frame, up to 0.6 off by frame 6); A shows its live pose afterwards. Also where
    the hat follows by an Armature constraint, whose targets are a list (the bake missed them)."""
    first, second, expected = hat_on_a_head(by)
    scene = bpy.context.scene
    scene.frame_set(3)
    head = checks.evaluated_mesh_points(first).copy()
    checks.select_only(second)
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=6) == {"FINISHED"}
    assert "baked" not in first.shapedeform
    np.testing.assert_allclose(checks.evaluated_mesh_points(first), head, atol=1e-5)
    errors = {}
    for frame in FRAMES:
        scene.frame_set(frame)
        errors[frame] = float(np.abs(checks.evaluated_mesh_points(second) - expected[frame]).max())
    assert max(errors.values()) < 1e-5, f"baked B off its live pose, per frame: {errors}"


def test_baking_again_follows_a_changed_leader(addon):
    """The head and the hat baked, the head's last key changed, both baked again: the hat's new
    bake sits on the head's new motion (the head's cage kept playing its old bake while it was
    baked again, and the hat was baked on that: 0.6 off); a bake cancelled half way leaves the
    old bakes playing."""
    first, second, expected_old = hat_on_a_head()
    handle = first.shapedeform.handles[-1].object
    scene = bpy.context.scene

    def key_last(offset):
        scene.frame_set(6)
        handle.location.y += offset
        handle.keyframe_insert("location", frame=6)

    key_last(-0.8)
    expected_new = {}
    for frame in FRAMES:
        scene.frame_set(frame)
        scene.frame_set(frame)  # twice: the hat follows the head's new shape
        expected_new[frame] = checks.evaluated_mesh_points(second).copy()
    assert np.abs(expected_new[6] - expected_old[6]).max() > 0.3
    key_last(0.8)
    bake = addon.shapedeform_addon.bake
    assert bake.bake_objects([first, second], 1, 6) == [first, second]
    key_last(-0.8)
    assert bake.bake_objects([first, second], 1, 6, cancelled=lambda: True) is None
    for frame in FRAMES:
        scene.frame_set(frame)
        np.testing.assert_allclose(checks.evaluated_mesh_points(second), expected_old[frame], atol=1e-5)
    assert bake.bake_objects([first, second], 1, 6) == [first, second]
    for frame in FRAMES:
        scene.frame_set(frame)
        np.testing.assert_allclose(checks.evaluated_mesh_points(second), expected_new[frame], atol=1e-4,
                                   err_msg=str(frame))


@pytest.mark.parametrize("pin", [None, "OVERLAP", "STARCH"])
def test_baking_a_rig_whose_handles_follow_nothing_solves_no_other_rig(addon, monkeypatch, pin):
    """The head baked alone (its handles keyed, following nothing; a pin rides on its own cage):
    the hat that follows it stays live and is not solved on each of the bake's frames, which it
    cannot change (a pin's cage parent counted as following another shape: 5 rigs, one baked,
    40 ms per frame against 8.5)."""
    first, second, expected = hat_on_a_head()
    shapedeform = addon.shapedeform_addon
    if pin is not None:
        checks.select_only(first)
        assert bpy.ops.shapedeform.add_handle(location=checks.world(first, [0.0, 0.0, 0.0]), kind=pin) == {"FINISHED"}
    solved = []
    pose_safely = shapedeform.rig.pose_safely
    monkeypatch.setattr(shapedeform.rig, "pose_safely", lambda obj, *args, **kwargs: (
        solved.append(obj.name), pose_safely(obj, *args, **kwargs))[1])
    with shapedeform.handlers.paused():
        assert shapedeform.bake.bake_objects([first], 1, 6) == [first]
    assert second.name not in solved and "baked" not in second.shapedeform


def test_a_bake_pushed_down_to_the_nla_is_replaced_and_cleared_with_its_action(addon):
    """README: the bake's keys push to the NLA as any keys do. Pushed down, the bake plays;
    baking again and Clear Bake remove its action (it was left behind with no user, one more
    on every bake); a new bake plays."""
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    expected = live(lambda: checks.evaluated_mesh_points(obj))
    bake = addon.shapedeform_addon.bake
    scene = bpy.context.scene

    def push_down():
        animation = obj.shapedeform.cage.data.shape_keys.animation_data
        action = animation.action
        animation.nla_tracks.new().strips.new(action.name, 1, action)
        animation.action = None

    handle_actions = {a.name for a in bpy.data.actions}
    bake.bake_objects([obj], 1, 6)
    push_down()
    scene.frame_set(4)
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), expected[4], atol=1e-5)
    bake.bake_objects([obj], 1, 6)  # replaces the pushed-down bake
    assert len(bpy.data.actions) == len(handle_actions) + 1
    push_down()
    checks.select_only(obj)
    assert bpy.ops.shapedeform.clear_bake() == {"FINISHED"}
    left = sorted({a.name for a in bpy.data.actions} - handle_actions)
    assert left == [], f"Clear Bake left {len(left)} action(s): {left}"
    bake.bake_objects([obj], 1, 6)
    scene.frame_set(3)
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), expected[3], atol=1e-5)
    # Pushed down and grouped into a meta strip with another (Shift+G in the NLA editor): the
    # strips inside it are searched too.
    push_down()
    track = obj.shapedeform.cage.data.shape_keys.animation_data.nla_tracks[-1]
    action = track.strips[0].action
    track.strips.new(action.name + " 2", int(track.strips[0].frame_end) + 1, action)
    for strip in track.strips:
        strip.select = True
    track.select = True
    window = bpy.context.window
    area = window.screen.areas[0]
    kind, area.type = area.type, "NLA_EDITOR"
    area.spaces.active.dopesheet.show_only_selected = False
    area.spaces.active.dopesheet.show_hidden = True  # the cage is hidden
    try:
        with bpy.context.temp_override(window=window, area=area, region=area.regions[-1]):
            assert bpy.ops.nla.meta_add() == {"FINISHED"}
    finally:
        area.type = kind
    assert [strip.type for strip in track.strips] == ["META"]
    checks.select_only(obj)
    assert bpy.ops.shapedeform.clear_bake() == {"FINISHED"}
    left = sorted({a.name for a in bpy.data.actions} - handle_actions)
    assert left == [], f"Clear Bake left {len(left)} action(s) of a meta strip: {left}"


def test_the_python_entry_point_bakes_the_scene_it_is_given(addon):
    """``bake_objects(..., scene=X)`` with another scene active poses X's frames from X's
    depsgraph (it read the active scene's, where the rig is not evaluated)."""
    shown = bpy.context.scene
    shot = bpy.data.scenes.new("Shot")
    bpy.context.window.scene = shot
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    expected = live(lambda: checks.evaluated_mesh_points(obj))
    bpy.context.window.scene = shown
    assert addon.shapedeform_addon.bake.bake_objects([obj], 1, 6, scene=shot) == [obj]
    bpy.context.window.scene = shot
    assert_plays_without_extension(lambda: checks.evaluated_mesh_points(obj), expected)


def test_binding_locks_the_interface_during_renders(addon):
    scene = bpy.context.scene
    scene.render.use_lock_interface = False
    grid()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert scene.render.use_lock_interface


def test_image_plane_bake_plays_without_the_extension(addon, tmp_path):
    """An image plane's rig bakes like any other."""
    from test_rig_image_plane import import_picture

    obj, _ = import_picture(tmp_path)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    points = checks.evaluated_mesh_points(obj)
    low, high = points.min(axis=0), points.max(axis=0)
    checks.add_handle(obj, low + 0.1 * (high - low))
    animate(checks.add_handle(obj, high - 0.1 * (high - low)), (0.0, 0.3, 0.0))
    expected = live(lambda: checks.evaluated_mesh_points(obj))
    assert np.abs(expected[6] - expected[1]).max() > 0.1
    assert addon.shapedeform_addon.bake.bake_objects([obj], 1, 6) == [obj]
    assert len(cage_keys(obj)) == 1 + len(FRAMES)
    assert_plays_without_extension(lambda: checks.evaluated_mesh_points(obj), expected)


# -- issue 15, defect 11: a rebake after unbind and bind on a baked frame

def monkey():
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    rest = drawing_points(obj, evaluated=False)
    rig(obj, rest[np.argmin(rest[:, 2])], rest[np.argmax(rest[:, 2])], (0.3, 0.0, 0.0))
    return obj


def frame_numbers(obj):
    return {layer.name: sorted(f.frame_number for f in layer.frames) for layer in obj.data.layers}


def test_bake_unbind_bind_on_a_baked_frame_and_bake_again(addon):
    obj = monkey()
    bake = addon.shapedeform_addon.bake
    bake.bake_objects([obj], 1, 6)
    scene = bpy.context.scene
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    scene.frame_set(3)  # a frame inside the old bake
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    rest = drawing_points(obj, evaluated=False)
    checks.add_handle(obj, checks.world(obj, rest[np.argmin(rest[:, 2])]))
    animate(checks.add_handle(obj, checks.world(obj, rest[np.argmax(rest[:, 2])])), (0.0, 0.0, 0.3))
    expected = live(lambda: drawing_points(obj))
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=6) == {"FINISHED"}
    assert all(numbers == [1] for numbers in frame_numbers(obj).values())
    assert_plays_without_extension(lambda: drawing_points(obj), expected)


def test_a_bake_that_cannot_be_written_changes_nothing(addon):
    """Every rig's write is checked before any previous bake is replaced."""
    mesh = grid()
    rig(mesh, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    pencil = monkey()
    bake = addon.shapedeform_addon.bake
    bake.bake_objects([mesh, pencil], 1, 6)
    keys = cage_keys(mesh)
    before = frame_numbers(pencil)
    cage = pencil.shapedeform.cage

    def edit_the_cage(done, total):  # as a script or handler might, once every frame is posed
        if done == total:
            cage.shape_key_clear()
            cage.data.vertices.add(1)

    with pytest.raises(addon.shapedeform_addon.errors.RigError, match="lost or changed its cage"):
        bake.bake_objects([mesh, pencil], 2, 4, progress=edit_the_cage)
    assert cage_keys(mesh) == keys
    assert list(mesh.shapedeform["baked"]) == list(pencil.shapedeform["baked"]) == [1, 6, 1]
    assert frame_numbers(pencil) == before


@pytest.mark.parametrize("place, reason", [(float("nan"), "'{handle}': its transform is not a finite number"),
                                           (1e30, "'Grid': the solve gave non-finite positions: its handle "
                                                  "'{handle}' is [0-9.]+e\\+29 shape sizes away")])
def test_a_frame_that_cannot_be_posed_is_named_and_nothing_is_baked(addon, tmp_path, capfd, place, reason):
    """A handle keyed at frame 4 to NaN, or so far that the solve overflows (frame 2 is on the
    way there): the bake stops, names the frame and the handle (it said "kept the last pose", of
    no frame), and leaves the file and the rig as they were, from the command line and the
    operator alike."""
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    handle = obj.shapedeform.handles[1].object
    handle.location.x = place
    handle.keyframe_insert("location", frame=4)
    path = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    saved = path.read_bytes()
    capfd.readouterr()
    assert addon.shapedeform_addon.cli.main(["bake", "--frames", "1-6"]) == 1
    said = "frame 2: " + reason.format(handle=re.escape(handle.name))
    assert re.search(said, capfd.readouterr().err)
    assert path.read_bytes() == saved
    checks.select_only(obj)
    with pytest.raises(RuntimeError, match=said):
        bpy.ops.shapedeform.bake(frame_start=1, frame_end=6)
    assert cage_keys(obj) == [] and "baked" not in obj.shapedeform


# -- issue 15, defect 12: one rule outside the baked range

def rigged_mesh():
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    return obj, lambda: checks.evaluated_mesh_points(obj)


def rigged_curve():
    obj = text_curve("I")
    rest = np.concatenate([p[:, :3] for p in curve_points(obj)])
    rig(obj, rest[np.argmin(rest[:, 1])], rest[np.argmax(rest[:, 1])], (0.4, 0.0, 0.0))
    return obj, lambda: checks.evaluated_vertices(obj)


def rigged_grease_pencil():
    obj = monkey()
    return obj, lambda: drawing_points(obj)


@pytest.mark.parametrize("make", [rigged_mesh, rigged_curve, rigged_grease_pencil])
def test_outside_the_baked_range_every_kind_holds_the_nearest_baked_frame(addon, make):
    obj, read = make()
    expected = live(read)
    assert np.abs(expected[4] - expected[2]).max() > 0.05
    addon.shapedeform_addon.bake.bake_objects([obj], 2, 4)
    addon_utils.disable(ADDON_MODULE, default_set=True)  # what plays is the bake alone
    try:
        scene = bpy.context.scene
        # (A grease-pencil layer shows nothing before its first keyframe, 1: see below.)
        before = [1] if obj.type == "GREASEPENCIL" else [1, 0, -5]
        for frame, shown in [(f, 2) for f in before] + [(5, 4), (9, 4), (3, 3)]:
            scene.frame_set(frame)
            np.testing.assert_allclose(read(), expected[shown], atol=1e-5, err_msg=f"frame {frame}")
    finally:
        addon_utils.enable(ADDON_MODULE, default_set=True)


def test_a_mesh_bake_with_a_step_has_no_fade_outside_its_range(addon):
    """Every other frame baked: the first and last keys hold, with no half fade before or after."""
    obj, read = rigged_mesh()
    expected = live(read)
    addon.shapedeform_addon.bake.bake_objects([obj], 2, 6, step=2)
    scene = bpy.context.scene
    for frame, shown in [(1, 2), (0, 2), (7, 6), (8, 6)]:
        scene.frame_set(frame)
        np.testing.assert_allclose(read(), expected[shown], atol=1e-5, err_msg=f"frame {frame}")


def test_a_grease_pencil_bake_adds_no_drawing_before_the_first_keyframe(addon):
    obj = monkey()
    addon.shapedeform_addon.bake.bake_objects([obj], -2, 7)
    assert frame_numbers(obj) == {"Fills": [1], "Lines": [1]}
    bpy.context.scene.frame_set(0)
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    assert all(layer.current_frame() is None for layer in evaluated.layers)


def test_the_documented_python_entry_point_imports(addon):
    """README names the function a script calls to bake; that name must import as written."""
    import importlib
    import os
    import re

    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    with open(os.path.join(root, "README.md"), encoding="utf-8") as readme:
        text = readme.read()
    paths = re.findall(r"`([\w.]+)\.bake_objects\(", text)
    assert paths, "README does not show how to call bake_objects from Python"
    for module_path in paths:
        function = getattr(importlib.import_module(module_path), "bake_objects")
        assert function is addon.shapedeform_addon.bake.bake_objects


def test_a_bake_past_blenders_last_frame_is_refused(addon):
    """Keys past frame 1,048,574 land on it: a bake that ran on wrote every later frame's key
    there and reported success; the operator's range stops at Blender's too."""
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    bake = addon.shapedeform_addon.bake
    for start, end in ((1048570, 1048580), (-1048580, -1048570)):
        with pytest.raises(ValueError, match="run past Blender's"):
            bake.bake_objects([obj], start, end)
    assert cage_keys(obj) == []
    assert (bake.FIRST_FRAME, bake.LAST_FRAME) == (-1048574, 1048574)
    # The operator too (its fields' hard limits clamped such a range and baked what was left).
    bpy.context.view_layer.objects.active = obj
    for start, end in ((1048570, 1048580), (-1048580, -1048570)):
        with pytest.raises(RuntimeError, match="run past Blender's"):
            bpy.ops.shapedeform.bake(frame_start=start, frame_end=end)
    assert cage_keys(obj) == []


def test_a_stepped_bake_bakes_its_last_frame(addon):
    """Frames 3-10 every 2nd baked 3, 5, 7 and 9: frame 10 held frame 9's pose."""
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bake(frame_start=3, frame_end=10, step=2) == {"FINISHED"}
    assert cage_keys(obj) == ["Basis", "sd_bake_0003", "sd_bake_0005", "sd_bake_0007", "sd_bake_0009", "sd_bake_0010"]


def test_between_and_outside_baked_frames_the_pose_blends_and_holds_as_drawn(addon):
    """A stepped bake (frames 2, 5, 8) plays linear blends between its frames (frame 3.5 is half
    of 2 and half of 5, as motion blur's subframes see it) and holds the nearest baked frame
    outside them; what the add-on reads as the shown pose (drawn over a baked rig, where handles
    are added) is what Blender plays, at each of those times."""
    rig_format = addon.shapedeform_addon.rig_format
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    scene = bpy.context.scene
    cage = obj.shapedeform.cage

    def shown():
        return np.asarray(rig_format.shown_pose(cage), dtype=np.float32)

    addon.shapedeform_addon.bake.bake_objects([obj], 2, 8, step=3)
    baked = {}
    for frame in (2, 5, 8):
        scene.frame_set(frame)
        baked[frame] = checks.evaluated_mesh_points(cage).copy()
    assert np.abs(baked[8] - baked[2]).max() > 0.3
    for frame, subframe, expected in ((3, 0.5, (baked[2] + baked[5]) / 2), (7, 0.0, (baked[5] + 2 * baked[8]) / 3),
                                      (0, 0.0, baked[2]), (12, 0.0, baked[8]), (5, 0.0, baked[5])):
        scene.frame_set(frame, subframe=subframe)
        played = checks.evaluated_mesh_points(cage)
        np.testing.assert_allclose(played, expected, atol=1e-5, err_msg=f"frame {frame + subframe}")
        np.testing.assert_allclose(shown(), played, atol=1e-5, err_msg=f"frame {frame + subframe}")


def test_every_frame_of_a_long_bake_plays_its_own_pose_alone(addon):
    """Keys of a bake placed where Blender placed them (a tenth apart, added one after the
    other) drifted from the times keyed for them: at 2,000 frames a baked frame blended in 1.5e-4
    of the next frame's pose (1.2e-3 at 20,000). Each key now sits exactly at the time it is
    keyed at: every baked frame shows its pose alone, and the pose read as shown is it."""
    shapedeform = addon.shapedeform_addon
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    cage = obj.shapedeform.cage
    rest = shapedeform.rig_format.rest_of(cage)
    frames = list(range(1, 3001))
    poses = rest[None] + np.random.default_rng(7).normal(size=(len(frames), *rest.shape)).astype(np.float32)
    shapedeform.bake._write_keys(cage, frames, 1, list(poses), frames)
    scene = bpy.context.scene
    for frame in (1, 2, 1499, 2048, 2999, 3000):
        scene.frame_set(frame)
        np.testing.assert_array_equal(checks.evaluated_mesh_points(cage), poses[frame - 1], err_msg=f"frame {frame}")
        np.testing.assert_allclose(shapedeform.rig_format.shown_pose(cage), poses[frame - 1], atol=1e-6)
    # Between frames the blend is linear, within what float32 holds of a key's place: near 205,
    # to 1.5e-5, a share of 1.5e-4 of the 0.1 between two keys.
    scene.frame_set(2047, subframe=0.25)
    step = np.abs(poses[2047] - poses[2046]).max()
    np.testing.assert_allclose(checks.evaluated_mesh_points(cage), 0.75 * poses[2046] + 0.25 * poses[2047],
                               atol=3e-4 * step)
    np.testing.assert_allclose(shapedeform.rig_format.shown_pose(cage), checks.evaluated_mesh_points(cage), atol=1e-5)


def test_an_earlier_versions_bake_plays_is_drawn_and_is_replaced(addon):
    """Bakes made before the keys were absolute (a relative key per frame, keyed 0 / 1 / 0) keep
    playing, are read as shown, stay put while a new bake poses live, and a new bake replaces
    them with one curve."""
    shapedeform = addon.shapedeform_addon
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    expected = live(lambda: checks.evaluated_mesh_points(obj))
    cage = obj.shapedeform.cage
    poses = live(lambda: checks.evaluated_mesh_points(cage))
    # As an earlier version wrote it.
    cage.shape_key_add(name="Basis", from_mix=False).data.foreach_set("co", shapedeform.rig_format.rest_of(cage).ravel())
    key = cage.data.shape_keys
    key[shapedeform.rig_format.BAKE_MARK] = True
    for frame in FRAMES:
        block = cage.shape_key_add(name=shapedeform.bake.key_name(frame), from_mix=False)
        block.data.foreach_set("co", poses[frame].ravel())
        for at, value in ((frame - 1, 0.0), (frame, 1.0), (frame + 1, 0.0)):
            if at in FRAMES:
                block.value = value
                block.keyframe_insert("value", frame=at)
    obj.shapedeform["baked"] = [1, 6, 1]
    scene = bpy.context.scene
    for frame in (4, 2):
        scene.frame_set(frame)
        np.testing.assert_allclose(checks.evaluated_mesh_points(obj), expected[frame], atol=1e-5)
        np.testing.assert_allclose(shapedeform.rig_format.shown_pose(cage), poses[frame], atol=1e-5)

    checks.select_only(obj)
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=6) == {"FINISHED"}
    key = cage.data.shape_keys
    assert not key.use_relative and len(key.key_blocks) == len(FRAMES) + 1
    assert_plays_without_extension(lambda: checks.evaluated_mesh_points(obj), expected)


def test_unbinding_a_copy_of_a_baked_rig_leaves_a_file_that_saves(addon, tmp_path):
    """A baked rig duplicated with its handles gets its own cage, a copy of the baked one. On
    Blender 4.5 and 5.0 the copy's shape keys have a user too many, so unbinding the copy left
    them behind pointing at nothing, and every later save raised."""
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=3) == {"FINISHED"}
    for o in bpy.context.selected_objects:
        o.select_set(False)
    for o in [obj] + [item.object for item in obj.shapedeform.handles]:
        o.select_set(True)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.object.duplicate() == {"FINISHED"}
    copy = next(o for o in bpy.context.selected_objects if o.type == "MESH")
    assert addon.shapedeform_addon.rig_format.is_owner(copy)  # a rig of its own, bake included
    keys = {k.session_uid for k in bpy.data.shape_keys}
    for o in bpy.context.selected_objects:
        o.select_set(False)
    bpy.context.view_layer.objects.active = copy
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert all(k.user is not None for k in bpy.data.shape_keys)
    assert len({k.session_uid for k in bpy.data.shape_keys}) == len(keys) - 1
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))  # raised on 4.5 and 5.0


def test_what_is_drawn_over_a_baked_rig_and_handles_added_to_it_take_the_bake_shown(addon):
    """A baked rig plays its keys and is not posed: the graph drawn over it (Show Graph) stayed
    at the pose the bake ended on (0.507 off the shape at frame 6), and a handle added at frame 6
    took its offsets from that pose, so the shape jumped 0.40 once the bake was cleared."""
    rig_format = addon.shapedeform_addon.rig_format
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    addon.shapedeform_addon.bake.bake_objects([obj], 1, 6)
    obj.shapedeform.show_overlay = True
    scene = bpy.context.scene
    world = np.array(rig_format.rig_space(obj))
    for frame in (1, 3, 6):
        scene.frame_set(frame)
        data = addon.shapedeform_addon.overlay.drawing_data(obj)
        cage = rig_format.shown_pose(obj.shapedeform.cage) @ world[:3, :3].T + world[:3, 3]
        edges = addon.shapedeform_addon.rig.get(obj).graph.edges.ravel()
        np.testing.assert_allclose(data["edges"], cage[edges], atol=1e-4, err_msg=f"frame {frame}")

    shown = checks.evaluated_mesh_points(obj).copy()
    middle = int(np.argmin(np.linalg.norm(checks.mesh_points(obj)[:, :2] - [0.5, 0.0], axis=1)))
    checks.select_only(obj)
    assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, shown[middle])) == {"FINISHED"}
    assert bpy.ops.shapedeform.clear_bake() == {"FINISHED"}
    scene.frame_set(6)
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), shown, atol=1e-3)


def test_a_copy_of_a_baked_rig_bakes_into_an_action_of_its_own(addon):
    """Shift+D of a baked rig with its handles gives the copy a rig of its own, its cage a copy
    of the baked one: the two Keys played one action, so retiming the copy's bake keys moved the
    original's pose (0.507 measured). The copy's Key gets a copy of the bake action, in its slot
    and marked, and Clear Bake on either removes only its own. A cage mesh two appended copies
    shared (Append with Reuse Data) is copied the same way."""
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    shapedeform = addon.shapedeform_addon
    shapedeform.bake.bake_objects([obj], 1, 6)
    expected = live(lambda: checks.evaluated_mesh_points(obj))
    copy = duplicate([obj] + [item.object for item in obj.shapedeform.handles], obj)
    assert shapedeform.rig_format.is_owner(copy)

    def bake_of(o):
        return o.shapedeform.cage.data.shape_keys.animation_data

    def bake_actions():
        return {a.name for a in bpy.data.actions if a.get(shapedeform.bake.MARK)}

    original, copied = bake_of(obj), bake_of(copy)
    assert copied.action != original.action and (original.action.users, copied.action.users) == (1, 1)
    assert copied.action.get(shapedeform.bake.MARK)
    assert copied.action_slot.identifier == original.action_slot.identifier
    for curve in shapedeform.compat.channelbag(copied.action, copied.action_slot).fcurves:
        for point in curve.keyframe_points:  # retimed in the Dope Sheet: 10 frames later
            for co in (point.co, point.handle_left, point.handle_right):
                co.x += 10
        curve.update()
    for frame in FRAMES:
        bpy.context.scene.frame_set(frame)
        np.testing.assert_allclose(checks.evaluated_mesh_points(obj), expected[frame], atol=1e-5)

    assert shapedeform.bake.clear(copy) == 6
    assert bake_actions() == {original.action.name}
    shared = obj.shapedeform.cage.data
    copy.shapedeform.cage.data = shared  # as two appends reusing data leave them
    assert shapedeform.duplicates.own_cage_mesh(copy) and copy.shapedeform.cage.data != shared
    assert bake_of(copy).action not in (None, original.action)
    assert shapedeform.bake.clear(copy) == 6 and shapedeform.bake.clear(obj) == 6
    assert bake_actions() == set()


def test_a_bake_says_it_is_out_of_date_once_what_it_was_made_from_changes(addon):
    """Re-keyed, moved, driven, added or removed handles, changed pins or settings left the old
    bake playing and nothing said so; the sidebar offered only Clear Bake. Now, as Blender's
    physics caches, the sidebar says the bake is out of date under its Baked line and offers
    Bake Again beside Clear Bake; baking again fits again. The Viewport budget, which a bake
    does not use, leaves it up to date."""
    from test_ui_overlay import drawn

    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    still, keyed = [item.object for item in obj.shapedeform.handles]
    for kind, x in (("STARCH", -0.5), ("OVERLAP", 0.5)):
        bpy.context.view_layer.objects.active = obj
        assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [x, 0.0, 0.0]), kind=kind) == {"FINISHED"}
    starch, overlap = [item.object for item in obj.shapedeform.handles[2:]]
    bake = addon.shapedeform_addon.bake
    bake_source = addon.shapedeform_addon.bake_source

    def key_again():
        keyed.location.y += 0.8
        keyed.keyframe_insert("location", frame=6)

    def move():
        still.location.x += 0.1

    def drive():
        still.driver_add("rotation_euler", 2).driver.expression = "0.2"

    def add_handle():
        checks.add_handle(obj, checks.world(obj, [0.0, 0.3, 0.0]))

    def remove_handle():
        checks.select_only(obj)
        assert bpy.ops.shapedeform.remove_handle(handle=obj.shapedeform.handles[-1].object.name) == {"FINISHED"}

    settings = [(obj.shapedeform, "weight_edge", 2.0), (obj.shapedeform, "preserve_area", True),
                (obj.shapedeform, "render_iterations", 12), (starch.shapedeform, "stiffness", 3.0),
                (overlap.shapedeform, "in_front", -1.0), (overlap.shapedeform, "extent", 0.5)]
    changes = [key_again, move, drive, add_handle, remove_handle] + [partial(setattr, *s) for s in settings]
    assert bake.bake_objects([obj], 1, 6) == [obj]
    checks.select_only(obj)
    for change in changes:
        assert not bake_source.is_out_of_date(obj)
        change()
        bpy.context.view_layer.update()
        assert bake_source.is_out_of_date(obj), change
        checks.select_only(obj)
        labels = drawn(bpy.context, labels=True)
        assert labels.index("Out of date: handles or settings changed since the bake") == \
            labels.index("Baked frames 1 to 6: the keyframes play, the rig waits") + 1
        assert {"shapedeform.bake", "shapedeform.clear_bake"} <= set(drawn(bpy.context))
        assert bake.bake_objects([obj], 1, 6) == [obj]
    assert not any(label.startswith("Out of date") for label in drawn(bpy.context, labels=True))
    obj.shapedeform.iterations = 3
    assert not bake_source.is_out_of_date(obj)


def test_a_render_names_the_rigs_whose_bakes_are_out_of_date(addon, tmp_path, capfd):
    """QA: a key edited after baking rendered the motion as baked, and only the sidebar said
    so; a farm's render leaves its log alone to read."""
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    checks.select_only(obj)
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=4) == {"FINISHED"}
    renders.camera_over((0.0, 0.0), 3.0)
    capfd.readouterr()
    renders.render(tmp_path / "up_to_date.png", size=16)
    assert "Bake Again" not in capfd.readouterr().err
    handle = obj.shapedeform.handles[1].object
    handle.location.y += 0.3
    handle.keyframe_insert("location", frame=4)
    bpy.context.view_layer.update()
    renders.render(tmp_path / "stale.png", size=16)
    assert "'Grid' plays a bake made before its rig last changed" in capfd.readouterr().err


def test_a_bake_is_out_of_date_once_an_armature_constraints_targets_change(addon):
    """A handle held by an Armature constraint: its targets are a list, which the bake's digest
    skipped, so another bone, another weight or a second target (each moving the shape) left
    the bake up to date."""
    bake, bake_source = addon.shapedeform_addon.bake, addon.shapedeform_addon.bake_source
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    armature = armature_following()
    armature.pose.bones["Bone"].location = (0.0, 0.0, 0.3)
    armature.pose.bones["Other"].rotation_euler.z = 0.8
    constraint = obj.shapedeform.handles[0].object.constraints.new("ARMATURE")
    target = constraint.targets.new()
    target.target, target.subtarget = armature, "Bone"

    def second_target():
        added = constraint.targets.new()
        added.target, added.subtarget = armature, "Bone"

    for change in (partial(setattr, target, "subtarget", "Other"), partial(setattr, target, "weight", 0.3),
                   second_target):
        assert bake.bake_objects([obj], 1, 3) == [obj]
        bpy.context.view_layer.update()
        assert not bake_source.is_out_of_date(obj)
        change()
        bpy.context.view_layer.update()
        assert bake_source.is_out_of_date(obj), change


def test_an_unchanged_bake_stays_up_to_date_over_frames_undo_saving_and_the_command_line(addon, tmp_path):
    """What the bake was made from is kept in the file: frames, undo and reopening leave an
    unchanged bake up to date, a bake made on the command line too; a bake from a file saved
    before bakes kept it is never said to be out of date."""
    shapedeform = addon.shapedeform_addon
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    checks.select_only(obj)
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=6) == {"FINISHED"}
    for frame in (3, 6, 1, 9, 0):
        bpy.context.scene.frame_set(frame)
        assert not shapedeform.bake_source.is_out_of_date(obj), frame
    bpy.ops.ed.undo_push(message="baked")
    obj.shapedeform.handles[0].object.location.x += 0.2
    bpy.ops.ed.undo_push(message="moved")
    assert shapedeform.bake_source.is_out_of_date(obj)
    assert bpy.ops.ed.undo() == {"FINISHED"}
    assert not shapedeform.bake_source.is_out_of_date(bpy.data.objects["Grid"])

    path = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Grid"]
    assert shapedeform.rig_format.is_baked(obj) and not shapedeform.bake_source.is_out_of_date(obj)
    assert shapedeform.cli.main(["bake", "--frames", "2-5"]) == 0
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Grid"]
    assert list(obj.shapedeform["baked"]) == [2, 5, 1] and not shapedeform.bake_source.is_out_of_date(obj)
    obj.shapedeform.handles[0].object.location.x += 0.2
    bpy.context.view_layer.update()  # a script's change counts once evaluated
    assert shapedeform.bake_source.is_out_of_date(obj)

    del obj.shapedeform.cage.data.shape_keys[shapedeform.rig_format.BAKE_SOURCE]  # as saved before
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Grid"]
    assert shapedeform.rig_format.is_baked(obj) and not shapedeform.bake_source.is_out_of_date(obj)


def rig_to_apply(rotation_mode=None, rotation=None, location=None, scale=(1.5, 1.5, 1.5)):
    """A grid turned and scaled by ``scale``, bound, a still handle (turned ``rotation`` in
    ``rotation_mode``, at ``location``) and a keyed one, baked on frames 1-4; (owner, still).

    (A scale that differs between axes skews a turned handle, which Apply Transform cannot
    give back: the handle then moves, and its bake is out of date.)"""
    obj = grid()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    still = checks.add_handle(obj, checks.world(obj, [-0.8, 0.1, 0.0]))
    animate(checks.add_handle(obj, checks.world(obj, [0.8, 0.0, 0.0])), (0.0, 0.3, 0.0))
    if rotation_mode is not None:
        still.rotation_mode = rotation_mode
        setattr(still, {"QUATERNION": "rotation_quaternion", "AXIS_ANGLE": "rotation_axis_angle"}.get(
            rotation_mode, "rotation_euler"), rotation)
    if location is not None:
        still.location = location
    obj.rotation_euler.z = 0.7
    obj.scale = scale
    bpy.context.view_layer.update()
    assert addon_module().bake.bake_objects([obj], 1, 4) == [obj]
    return obj, still


def addon_module():
    import importlib
    return importlib.import_module(f"{ADDON_MODULE}.shapedeform_addon")


def apply_rotation_and_scale(obj):
    checks.select_only(obj)
    assert bpy.ops.object.transform_apply(location=False, rotation=True, scale=True) == {"FINISHED"}
    bpy.context.view_layer.update()


@pytest.mark.parametrize("rotation_mode, rotation", [("QUATERNION", (-0.5, 0.0, 0.0, 0.8660254)),
                                                     ("AXIS_ANGLE", (-2.5, 0.0, 0.0, 1.0)),
                                                     ("XYZ", (0.0, 0.0, np.pi))])
def test_apply_transform_on_the_owner_leaves_a_bake_up_to_date_however_it_writes_a_rotation(addon, rotation_mode,
                                                                                              rotation):
    """Apply Rotation & Scale on the owner writes an unkeyed handle's rotation another way of
    those that make the same turn (-q for a quaternion q, 2.5 about -Z for -2.5 about Z, -pi
    for pi): the digest hashed the values, and the bake said it was out of date. A rotation no
    key sets counts by the turn it makes; an Euler rotation is written back near its angles."""
    bake = addon.shapedeform_addon.bake
    bake_source = addon.shapedeform_addon.bake_source
    obj, still = rig_to_apply(rotation_mode, rotation)
    apply_rotation_and_scale(obj)
    assert not bake_source.is_out_of_date(obj)
    if rotation_mode == "XYZ":
        assert still.rotation_euler.z == pytest.approx(np.pi, abs=1e-5)
    still.matrix_basis = Matrix.Rotation(0.01, 4, "Z") @ still.matrix_basis  # a turn, however small, is a change
    bpy.context.view_layer.update()
    assert bake_source.is_out_of_date(obj)


def test_a_handle_keyed_on_one_euler_channel_keeps_its_pose_after_apply_transform_on_the_owner(addon):
    """Apply Transform on the owner had the handles' rotations written from their matrices:
    an Euler rotation came back as another set of angles making the same turn, (-0.64, 1.14,
    Z + pi) for (2.5, 2.0, Z), and a handle keyed on Z alone then played its keyed Z with the
    new X and Y, another turn. The angles are written back near what they were."""
    obj, still = rig_to_apply("XYZ", (2.5, 2.0, 0.3))
    still.keyframe_insert("rotation_euler", index=2, frame=1)
    still.rotation_euler.z = 0.9
    still.keyframe_insert("rotation_euler", index=2, frame=4)
    scene = bpy.context.scene
    scene.frame_set(4)
    before = np.array(still.matrix_world)
    apply_rotation_and_scale(obj)
    scene.frame_set(1)
    scene.frame_set(4)
    np.testing.assert_allclose(np.array(still.matrix_world), before, atol=1e-5)


def test_rounding_errors_of_apply_transform_leave_a_bake_up_to_date(addon):
    """The digest hashed values rounded to 5 decimals: a rounding error of Apply Transform that
    crossed a rounding step (x = -0.70000503 written back as -0.70000499) said the bake was out
    of date. Numbers no key sets are compared within a tolerance (1e-5) instead."""
    bake = addon.shapedeform_addon.bake
    bake_source = addon.shapedeform_addon.bake_source
    obj, still = rig_to_apply(location=(-0.70000503, 0.1, 0.0), scale=(1.7, 1.3, 1.0))
    apply_rotation_and_scale(obj)
    assert round(still.location.x, 5) != round(-0.70000503, 5)  # the error crossed a step
    assert not bake_source.is_out_of_date(obj)
    still.location.x += 1e-3
    bpy.context.view_layer.update()
    assert bake_source.is_out_of_date(obj)


def test_renaming_what_drivers_read_leaves_a_bake_up_to_date(addon):
    """The digest hashed the names of the objects a handle's drivers read: renaming one (a
    controller, another handle) said the bake was out of date. Which objects drivers read is
    left out, as what they read is (the README says so)."""
    bake = addon.shapedeform_addon.bake
    bake_source = addon.shapedeform_addon.bake_source
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    still, keyed = [item.object for item in obj.shapedeform.handles]
    controller = bpy.data.objects.new("Controller", None)
    bpy.context.scene.collection.objects.link(controller)
    for handle, target, transform in ((still, controller, "LOC_X"), (keyed, still, "ROT_Z")):
        driver = handle.driver_add("delta_location", 1).driver
        driver.type = "SUM"
        variable = driver.variables.new()
        variable.type = "TRANSFORMS"
        variable.targets[0].id, variable.targets[0].transform_type = target, transform
    bpy.context.view_layer.update()
    assert bake.bake_objects([obj], 1, 6) == [obj]
    controller.name, still.name = "Controller renamed", "Left hand"
    assert not bake_source.is_out_of_date(obj)


def test_nla_tweak_mode_leaves_a_bake_up_to_date(addon):
    """In NLA tweak mode the action tweaked is the active action as well as its strip's: the
    digest counted its keys twice, and said the bake was out of date."""
    bake = addon.shapedeform_addon.bake
    bake_source = addon.shapedeform_addon.bake_source
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    animation = obj.shapedeform.handles[1].object.animation_data
    track = animation.nla_tracks.new()
    strip = track.strips.new("Walk", 1, animation.action)
    strip.action_slot = animation.action_slot
    animation.action = None
    bpy.context.view_layer.update()
    assert bake.bake_objects([obj], 1, 6) == [obj]
    track.select = strip.select = True
    animation.nla_tracks.active = track
    animation.use_tweak_mode = True
    bpy.context.view_layer.update()
    assert animation.action is not None and not bake_source.is_out_of_date(obj)


def location_y_curve(handle):
    """The F-curve of ``handle``'s location Y in the action it plays (active, or its strip's)."""
    from bpy_extras import anim_utils

    animation = handle.animation_data
    holder = animation if animation.action is not None else animation.nla_tracks[0].strips[0]
    bag = anim_utils.action_get_channelbag_for_slot(holder.action, holder.action_slot)
    return next(curve for curve in bag.fcurves if curve.data_path == "location" and curve.array_index == 1)


def in_nla(handle):
    """Push ``handle``'s action down to an NLA strip; (track, strip)."""
    animation = handle.animation_data
    track = animation.nla_tracks.new()
    strip = track.strips.new("Move", 1, animation.action)
    strip.action_slot = animation.action_slot
    animation.action = None
    return track, strip


def ease(handle, interpolation, **settings):
    for point in location_y_curve(handle).keyframe_points:
        point.interpolation = interpolation
        for name, value in settings.items():
            setattr(point, name, value)


def animate_influence(strip):
    strip.use_animated_influence = True
    strip.influence = 0.3
    strip.keyframe_insert("influence", frame=1)


def add_noise(handle):
    location_y_curve(handle).modifiers.new("NOISE").strength = 0.0


def stronger_noise(handle, _):
    location_y_curve(handle).modifiers[0].strength = 2.0


def limit_y(handle, max_y=0.1):
    constraint = handle.constraints.new("LIMIT_LOCATION")
    constraint.use_max_y, constraint.max_y, constraint.owner_space = True, max_y, "LOCAL"
    return constraint


def silenced(handle, how):
    """``handle``'s keys kept from playing: its curve muted, or pushed into the NLA and the track
    muted or the NLA turned off."""
    if how == "curve":
        location_y_curve(handle).mute = True
        return None
    track, _ = in_nla(handle)
    if how == "track":
        track.mute = True
    else:
        handle.animation_data.use_nla = False
    return None


def moved_by_hand(handle, _):
    handle.location.y += 0.5


# What changes a bake made again (each moved the baked poses 0.28-1.02), after what setup.
SETUPS = {
    # Moved by hand where its keys do not play (QA: left up to date, the bake 0.5 off).
    "curve muted, moved": (lambda h: silenced(h, "curve"), moved_by_hand),
    "track muted, moved": (lambda h: silenced(h, "track"), moved_by_hand),
    "NLA off, moved": (lambda h: silenced(h, "nla"), moved_by_hand),
    "noise": (add_noise, stronger_noise),
    "easing": (lambda h: ease(h, "BOUNCE", easing="EASE_IN"), lambda h, _: ease(h, "BOUNCE", easing="EASE_OUT")),
    "back": (lambda h: ease(h, "BACK", back=1.0), lambda h, _: ease(h, "BACK", back=5.0)),
    "strip influence": (in_nla, lambda h, nla: animate_influence(nla[1])),
    "track mute": (in_nla, lambda h, nla: setattr(nla[0], "mute", True)),
    "strip scale": (in_nla, lambda h, nla: setattr(nla[1], "scale", 2.0)),
    "strip blend": (in_nla, lambda h, nla: setattr(nla[1], "blend_type", "ADD")),
    "constraint added": (lambda h: None, lambda h, _: limit_y(h)),
    "constraint setting": (limit_y, lambda h, constraint: setattr(constraint, "max_y", 0.3)),
    "parent cleared": (lambda h: None, lambda h, _: setattr(h, "parent", None)),
}


@pytest.mark.parametrize("what", SETUPS)
def test_a_bake_says_it_is_out_of_date_once_how_its_keys_play_or_its_handles_hang_changed(addon, what):
    """A curve's modifiers' settings (only their types counted), its keys' easing, the NLA
    tracks and strips playing them, a constraint on a handle and its parent went unnoticed:
    a bake made again moved 0.28-1.02, and the sidebar said nothing."""
    bake = addon.shapedeform_addon.bake
    bake_source = addon.shapedeform_addon.bake_source
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    keyed = obj.shapedeform.handles[1].object
    setup, change = SETUPS[what]
    made = setup(keyed)
    bpy.context.view_layer.update()
    assert bake.bake_objects([obj], 1, 6) == [obj]
    for frame in (3, 6, 1):
        bpy.context.scene.frame_set(frame)
        assert not bake_source.is_out_of_date(obj), frame
    change(keyed, made)
    bpy.context.view_layer.update()
    assert bake_source.is_out_of_date(obj)


def test_a_bake_of_handles_played_by_the_nla_constrained_and_eased_stays_up_to_date(addon, tmp_path):
    """What a bake now counts of how keys play (strips blending in and out, an animated
    influence, a constraint's own inverse, modifiers, easing) leaves an unchanged bake up to
    date over frames, undo and reopening."""
    bake = addon.shapedeform_addon.bake
    bake_source = addon.shapedeform_addon.bake_source
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    still, keyed = [item.object for item in obj.shapedeform.handles]
    location_y_curve(keyed).modifiers.new("NOISE").strength = 0.1
    ease(keyed, "ELASTIC", amplitude=0.5)
    track, strip = in_nla(keyed)
    strip.blend_in = strip.blend_out = 2.0
    follow = still.constraints.new("CHILD_OF")
    follow.target = keyed
    follow.inverse_matrix = Matrix.Translation((0.1, 0.0, 0.0))
    limit_y(keyed).influence = 0.5
    bpy.context.view_layer.update()
    checks.select_only(obj)
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=6) == {"FINISHED"}
    for frame in (2, 5, 1, 7, 4):
        bpy.context.scene.frame_set(frame)
        assert not bake_source.is_out_of_date(obj), frame
    bpy.ops.ed.undo_push(message="baked")
    keyed.constraints[0].influence = 0.6
    bpy.ops.ed.undo_push(message="changed")
    assert bake_source.is_out_of_date(obj)
    assert bpy.ops.ed.undo() == {"FINISHED"}
    assert not bake_source.is_out_of_date(bpy.data.objects["Grid"])
    path = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    bpy.context.scene.frame_set(3)
    assert not bake_source.is_out_of_date(bpy.data.objects["Grid"])


def test_the_bake_operator_bakes_the_preview_range_while_it_is_on(addon, tmp_path):
    """Blender's Bake Action bakes the preview range while it is on; Bake Deformation baked the
    scene's frame range (1-250 for a preview range of 2-5). Frames given still win, and the
    command line bakes the scene's frame range, the one that renders."""
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 8
    scene.use_preview_range = True
    scene.frame_preview_start, scene.frame_preview_end = 2, 5
    checks.select_only(obj)
    for given, baked in [({}, [2, 5]), ({"frame_start": 1, "frame_end": 6}, [1, 6]), ({"frame_end": 3}, [2, 3])]:
        assert bpy.ops.shapedeform.bake(**given) == {"FINISHED"}
        assert list(obj.shapedeform["baked"])[:2] == baked, given
    scene.use_preview_range = False
    assert bpy.ops.shapedeform.bake() == {"FINISHED"}
    assert list(obj.shapedeform["baked"])[:2] == [1, 8]

    scene.use_preview_range = True
    path = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    assert addon.shapedeform_addon.cli.main(["bake"]) == 0
    bpy.ops.wm.open_mainfile(filepath=path)
    assert list(bpy.data.objects["Grid"].shapedeform["baked"])[:2] == [1, 8]


def bake_again():
    """Press the sidebar's Bake Again: the bake operator with the properties the panel gives it."""
    from test_ui_overlay import RecordingLayout

    layout = RecordingLayout()
    bpy.types.SHAPEDEFORM_PT_animation.draw(SimpleNamespace(layout=layout), bpy.context)
    properties = next(vars(given) for idname, given in layout.buttons if idname == "shapedeform.bake")
    return bpy.ops.shapedeform.bake(**properties)


def test_bake_again_bakes_the_frames_and_step_of_the_bake_it_replaces(addon):
    """Bake Again pressed the bake operator with nothing given: a bake of frames 1-12 every 2
    came back as 1-40 every 1, and a farm's bake of 1-40 as 5-8 while the preview range was on.
    It gives the operator the baked frames and step; the first bake keeps the scene's."""
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 40
    checks.select_only(obj)
    assert bake_again() == {"FINISHED"}  # the first bake: Bake Deformation, the scene's frames
    assert list(obj.shapedeform["baked"]) == [1, 40, 1]
    addon.shapedeform_addon.bake.bake_objects([obj], 1, 12, step=2)
    assert bake_again() == {"FINISHED"}
    assert list(obj.shapedeform["baked"]) == [1, 12, 2]
    addon.shapedeform_addon.bake.bake_objects([obj], 1, 40)
    scene.use_preview_range = True
    scene.frame_preview_start, scene.frame_preview_end = 5, 8
    assert bake_again() == {"FINISHED"}
    assert list(obj.shapedeform["baked"]) == [1, 40, 1]


def test_bake_again_of_several_rigs_bakes_each_over_its_own_bake(addon):
    """Two rigs baked apart (1-12 every 2, and 5-9), both selected, the first active: Bake Again
    baked both over the active one's frames (the second came back as 1-12 every 2). Each is
    baked over its own bake's frames and step, and plays what it played; a third rig, never
    baked, takes the active one's."""
    bake = addon.shapedeform_addon.bake
    first, second, third = grid("First"), grid("Second"), grid("Third")
    for k, obj in enumerate((first, second, third)):
        obj.location.x = 3.0 * k
        bpy.context.view_layer.update()
        rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    bake.bake_objects([first], 1, 12, step=2)
    bake.bake_objects([second], 5, 9)
    scene = bpy.context.scene
    played = {}
    for frame in range(1, 13):
        scene.frame_set(frame)
        played[frame] = checks.evaluated_mesh_points(second).copy()
    checks.select_only(first)
    second.select_set(True)
    third.select_set(True)
    assert bake_again() == {"FINISHED"}
    assert [list(o.shapedeform["baked"]) for o in (first, second, third)] == [[1, 12, 2], [5, 9, 1], [1, 12, 2]]
    assert cage_keys(second)[1:] == [bake.key_name(f) for f in range(5, 10)]
    for frame in range(1, 13):
        scene.frame_set(frame)
        np.testing.assert_allclose(checks.evaluated_mesh_points(second), played[frame], atol=1e-5)


def test_whether_a_bake_is_out_of_date_is_worked_out_once_until_what_it_depends_on_changes(addon, monkeypatch):
    """The sidebar asked on every redraw, and each answer read every key of every handle (17.9
    ms for 30 handles keyed on 500 frames). The answer is kept per owner: redrawing works it out
    once; an update of the rig (a handle moved, a setting), of an action (a key edited, a
    modifier's setting, evaluated with a frame change too), undo and baking drop it."""
    from test_ui_overlay import drawn

    bake = addon.shapedeform_addon.bake
    bake_source = addon.shapedeform_addon.bake_source
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    still, keyed = [item.object for item in obj.shapedeform.handles]
    assert bake.bake_objects([obj], 1, 6) == [obj]
    checks.select_only(obj)
    worked_out = []
    fingerprint = bake_source.fingerprint
    monkeypatch.setattr(bake_source, "fingerprint", lambda owner: worked_out.append(owner.name) or fingerprint(owner))
    for _ in range(5):
        drawn(bpy.context, labels=True)
        assert not bake_source.is_out_of_date(obj)
    assert worked_out == ["Grid"]

    def edit_a_key():
        location_y_curve(keyed).keyframe_points[-1].co.y += 0.3
        bpy.context.view_layer.update()

    def add_noise_and_change_frames():
        location_y_curve(keyed).modifiers.new("NOISE").strength = 1.0
        bpy.context.scene.frame_set(3)

    def move():
        still.location.x += 0.1
        bpy.context.view_layer.update()

    def change_a_setting():
        obj.shapedeform.weight_edge = 2.5
        bpy.context.view_layer.update()

    def undo():
        bpy.ops.ed.undo_push(message="before")
        move()
        bpy.ops.ed.undo_push(message="moved")
        assert bake_source.is_out_of_date(obj)
        assert bpy.ops.ed.undo() == {"FINISHED"}

    for change, out_of_date in [(edit_a_key, True), (add_noise_and_change_frames, True), (move, True),
                                (change_a_setting, True), (undo, False)]:
        obj = bpy.data.objects["Grid"]
        still, keyed = [item.object for item in obj.shapedeform.handles]
        assert bake.bake_objects([obj], 1, 6) == [obj]
        assert not bake_source.is_out_of_date(obj)
        change()
        assert bake_source.is_out_of_date(bpy.data.objects["Grid"]) == out_of_date, change


def test_a_duplicate_following_a_baked_rig_says_whether_the_rig_s_bake_is_out_of_date(addon):
    """is_out_of_date on a duplicate that follows the rig (Alt+D) read the duplicate's own copy
    of the rig's settings: it stayed up to date while the rig's changed. It reads the rig's
    owner, as for a handle."""
    bake = addon.shapedeform_addon.bake
    bake_source = addon.shapedeform_addon.bake_source
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    assert bake.bake_objects([obj], 1, 6) == [obj]
    checks.select_only(obj)
    assert bpy.ops.object.duplicate_move_linked() == {"FINISHED"}
    bpy.context.view_layer.update()
    follower = bpy.context.active_object
    assert addon.shapedeform_addon.rig_format.is_follower(follower)
    assert not bake_source.is_out_of_date(follower)
    obj.shapedeform.weight_edge = 3.0
    bpy.context.view_layer.update()
    assert bake_source.is_out_of_date(follower) and bake_source.is_out_of_date(obj.shapedeform.handles[0].object)


def test_a_copy_of_a_baked_rig_names_its_bake_action_after_its_own_cage(addon):
    """A copy of a baked rig with a rig of its own got a copy of the bake action named after
    the original's cage ("Grid Cage Shape Deform Bake.001"); it is named after its own cage, as
    a bake of it makes it ("Grid Cage.001 Shape Deform Bake"), and so is the copy made for a
    cage mesh two appended rigs shared."""
    shapedeform = addon.shapedeform_addon
    obj = grid()
    rig(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], (0.0, 0.5, 0.0))
    assert shapedeform.bake.bake_objects([obj], 1, 6) == [obj]
    for o in [obj] + [item.object for item in obj.shapedeform.handles]:
        o.select_set(True)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.object.duplicate() == {"FINISHED"}
    bpy.context.view_layer.update()
    copy = next(o for o in bpy.context.selected_objects if o.type == "MESH")

    def bake_action(o):
        return o.shapedeform.cage.data.shape_keys.animation_data.action.name

    assert (bake_action(obj), bake_action(copy)) == ("Grid Cage Shape Deform Bake", "Grid Cage.001 Shape Deform Bake")
    shapedeform.bake.clear(copy)
    copy.shapedeform.cage.data = obj.shapedeform.cage.data  # as two appends reusing data leave them
    assert shapedeform.duplicates.own_cage_mesh(copy)
    assert bake_action(copy) == "Grid Cage.001 Shape Deform Bake"
