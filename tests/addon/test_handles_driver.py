# SPDX-License-Identifier: GPL-3.0-or-later
"""The driver that keeps a rig's handles and pins evaluated wherever the bound object is
(``rig_format.keep_handles_evaluated``): made, kept and removed through the workflows that touch
an object's animation data, duplicates, libraries, the extension disabled and enabled."""

import addon_utils
import bpy
import numpy as np
import pytest

import rig_checks as checks
from test_rig_mesh import grid, rig_with_two_handles

PATH = 'shapedeform.handles_watched'  # rig_format.HANDLES_WATCHED


def watched(obj):
    animation = obj.animation_data
    return animation.drivers.find(PATH) if animation is not None else None


def targets(obj):
    fcurve = watched(obj)
    return None if fcurve is None else [(v.targets[0].id, v.type, v.targets[0].data_path)
                                        for v in fcurve.driver.variables]


def expected_targets(owner):
    wanted = []
    for item in owner.shapedeform.handles:
        h = item.object
        if h is None or not h.users_collection:
            continue
        if h.shapedeform.pin_kind == "POSITION":
            wanted.append((h, "TRANSFORMS", ""))
        elif h.shapedeform.pin_kind == "OVERLAP":
            wanted += [(h, "SINGLE_PROP", "shapedeform.in_front"), (h, "SINGLE_PROP", "shapedeform.extent")]
        else:
            wanted += [(h, "SINGLE_PROP", "shapedeform.stiffness"), (h, "SINGLE_PROP", "shapedeform.extent")]
    return wanted


def assert_valid(obj):
    fcurve = watched(obj)
    assert fcurve is not None, f"{obj.name}: no handles driver"
    assert fcurve.is_valid, f"{obj.name}: fcurve invalid"
    assert fcurve.driver.is_valid, f"{obj.name}: driver invalid"
    for v in fcurve.driver.variables:
        assert v.is_name_valid, f"{obj.name}: variable {v.name} invalid"
        assert v.targets[0].id is not None, f"{obj.name}: variable {v.name} has no target"


def duplicate(objects, active, linked=False):
    for o in bpy.context.selected_objects:
        o.select_set(False)
    for o in objects:
        o.select_set(True)
    bpy.context.view_layer.objects.active = active
    assert bpy.ops.object.duplicate(linked=linked) == {"FINISHED"}
    copy = bpy.context.active_object
    bpy.context.view_layer.update()
    return copy


# -- followers: their drivers must follow the owner's handle list ---------------------------------

@pytest.mark.parametrize("linked", [False, True], ids=["Shift+D", "Alt+D"])
def test_follower_driver_tracks_owner_handle_add_and_remove(addon, linked):
    original, left, right = rig_with_two_handles()
    copy = duplicate([original], original, linked)
    copy.location.x += 3.0
    bpy.context.view_layer.update()
    assert addon.shapedeform_addon.rig_format.is_follower(copy)
    assert targets(copy) == expected_targets(original)

    third = checks.add_handle(original, checks.world(original, [0.0, 0.0, 0.0]))
    bpy.context.view_layer.update()
    assert targets(original) == expected_targets(original)
    assert targets(copy) == expected_targets(original), "follower's driver misses the added handle"

    checks.select_only(original)
    assert bpy.ops.shapedeform.remove_handle(handle=left.name) == {"FINISHED"}
    bpy.context.view_layer.update()
    assert targets(original) == expected_targets(original)
    assert_valid(copy)
    assert targets(copy) == expected_targets(original), "follower's driver still names the removed handle"


def test_follower_in_other_scene_plays_a_handle_added_after_duplicating(addon):
    """The README: a copy moved to another scene plays its rig's animation there. A handle
    added to the owner after the copy was made, keyed, must drive the copy in the shot."""
    original, left, right = rig_with_two_handles()
    first = bpy.context.scene
    copy = duplicate([original], original)
    shot = bpy.data.scenes.new("Shot")
    shot.collection.objects.link(copy)
    first.collection.objects.unlink(copy)
    bpy.context.view_layer.update()
    # back in the first scene, add a third handle in the middle and key it
    third = checks.add_handle(original, checks.world(original, [0.0, 0.0, 0.0]))
    third.keyframe_insert("location", frame=1)
    third.location.y += 0.6
    third.keyframe_insert("location", frame=10)
    first.frame_set(1)
    bpy.context.window.scene = shot
    mid = np.argmin(np.linalg.norm(checks.mesh_points(copy)[:, :2], axis=1))
    ys = []
    for frame in (1, 10):
        shot.frame_set(frame)
        ys.append(float(checks.evaluated_mesh_points(copy)[mid, 1]))
    assert ys[1] - ys[0] == pytest.approx(0.6, abs=0.05), ys


def test_copy_of_a_copy_has_a_valid_driver(addon):
    original, left, right = rig_with_two_handles()
    copy = duplicate([original], original)
    copy2 = duplicate([copy], copy, linked=True)
    for o in (original, copy, copy2):
        assert_valid(o)
        assert targets(o) == expected_targets(original), o.name
    checks.select_only(copy2)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert copy2.animation_data is None
    assert_valid(copy)


# -- the user's own animation data -----------------------------------------------------------

def snapshot(obj):
    ad = obj.animation_data
    if ad is None:
        return None
    drivers = [(f.data_path, f.array_index, f.driver.type, f.driver.expression,
                [(v.name, v.type, v.targets[0].id, v.targets[0].data_path, v.targets[0].transform_type)
                 for v in f.driver.variables], len(f.modifiers))
               for f in ad.drivers if f.data_path != PATH]
    action = ad.action.name if ad.action else None
    nla = [(t.name, [(s.name, s.action.name if s.action else None, s.frame_start, s.frame_end) for s in t.strips])
           for t in ad.nla_tracks]
    return dict(drivers=drivers, action=action, nla=nla, influence=ad.action_influence,
                blend=ad.action_blend_type, extrapolation=ad.action_extrapolation, use_nla=ad.use_nla)


def users_animation(obj, with_action=True, with_nla=False):
    control = bpy.data.objects.new("Control", None)
    bpy.context.scene.collection.objects.link(control)
    control.location.x = 0.5
    fc = obj.driver_add("location", 2)
    fc.driver.type = "AVERAGE"
    var = fc.driver.variables.new()
    var.type = "TRANSFORMS"
    var.targets[0].id = control
    var.targets[0].transform_type = "LOC_X"
    if with_action:
        obj.rotation_euler.z = 0.0
        obj.keyframe_insert("rotation_euler", index=2, frame=1)
        obj.rotation_euler.z = 0.3
        obj.keyframe_insert("rotation_euler", index=2, frame=10)
    if with_nla:
        ad = obj.animation_data
        track = ad.nla_tracks.new()
        track.name = "Walk"
        track.strips.new("walk", 1, ad.action)
        ad.action = None
    bpy.context.view_layer.update()
    return control


@pytest.mark.parametrize("with_nla", [False, True], ids=["action", "nla"])
def test_users_drivers_actions_and_nla_survive_bind_add_unbind(addon, with_nla, quiet):
    obj = grid()
    control = users_animation(obj, with_nla=with_nla)
    before = snapshot(obj)
    assert before is not None
    left, right = checks.bind_with_handles(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    assert snapshot(obj) == before
    assert_valid(obj)
    right.location.y += 0.3
    bpy.context.view_layer.update()
    bpy.context.scene.frame_set(5)
    assert snapshot(obj) == before
    # the user's driver still works
    control.location.x = 0.9
    bpy.context.view_layer.update()
    assert obj.location.z == pytest.approx(0.9)
    checks.select_only(obj)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert snapshot(obj) == before
    assert not obj.animation_data or obj.animation_data.drivers.find(PATH) is None


def test_empty_animation_data_from_before_bind_is_kept_on_unbind(addon):
    """Unbind leaves animation_data as it was before Bind (the brief): it existed (empty)."""
    obj = grid()
    obj.animation_data_create()
    obj.animation_data.action_influence = 0.5  # a user's setting on it
    checks.bind_with_handles(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    checks.select_only(obj)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert obj.animation_data is not None, "Unbind removed animation data the object had before Bind"
    assert obj.animation_data.action_influence == 0.5


def test_user_removes_action_after_bind_then_unbind(addon, quiet):
    obj = grid()
    users_animation(obj)
    checks.bind_with_handles(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    before = snapshot(obj)
    checks.select_only(obj)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert snapshot(obj) == before


# -- keying custom properties -----------------------------------------------------------------

def view3d_override():
    window = bpy.context.window_manager.windows[0]
    area = next(a for a in window.screen.areas if a.type == "VIEW_3D")
    region = next(r for r in area.regions if r.type == "WINDOW")
    return bpy.context.temp_override(window=window, area=area, region=region)


def test_pressing_i_with_custom_properties_on_the_owner(addon, quiet):
    """Preferences > Animation > Default Key Channels with Custom Properties on (Blender 4.2+):
    pressing I on the bound object. Unbind must leave no F-Curve pointing at the gone property."""
    from bpy_extras import anim_utils
    obj = grid()
    checks.bind_with_handles(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    checks.select_only(obj)
    prefs = bpy.context.preferences.edit
    old = set(prefs.key_insert_channels)
    prefs.key_insert_channels = {"LOCATION", "ROTATION", "SCALE", "CUSTOM_PROPS"}
    try:
        with view3d_override():
            assert bpy.ops.anim.keyframe_insert() == {"FINISHED"}
    finally:
        prefs.key_insert_channels = old
    checks.select_only(obj)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    bag = anim_utils.action_get_channelbag_for_slot(obj.animation_data.action, obj.animation_data.action_slot)
    bpy.context.scene.frame_set(2)
    for f in bag.fcurves:
        assert PATH not in f.data_path, f"dangling F-Curve {f.data_path} (is_valid={f.is_valid})"


# -- the extension disabled with a rigged file open ------------------------------------------

def pinned_rig():
    obj, left, right = rig_with_two_handles()
    checks.select_only(obj)
    assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.0, 0.0, 0.0]), kind="OVERLAP") == {"FINISHED"}
    assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.5, 0.0, 0.0]), kind="STARCH") == {"FINISHED"}
    right.keyframe_insert("location", frame=1)
    right.location.y += 0.4
    right.keyframe_insert("location", frame=10)
    bpy.context.view_layer.update()
    return obj, left, right


def test_disabled_extension_prints_nothing_and_driver_stays_valid(addon, tmp_path, capfd):
    module = addon.__name__
    obj, left, right = pinned_rig()
    scene = bpy.context.scene
    for f in (1, 5, 10):
        scene.frame_set(f)
    assert_valid(obj)
    capfd.readouterr()
    addon_utils.disable(module, default_set=True)
    try:
        for f in range(1, 11):
            scene.frame_set(f)
        out, err = capfd.readouterr()
        assert "rror" not in out + err and "Traceback" not in out + err, out + err
        path = str(tmp_path / "saved_disabled.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path)
        bpy.ops.wm.open_mainfile(filepath=path)
        for f in range(1, 4):
            bpy.context.scene.frame_set(f)
        out, err = capfd.readouterr()
        assert "rror" not in out + err and "Traceback" not in out + err, out + err
    finally:
        addon_utils.enable(module, default_set=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Grid"]
    for f in (1, 10):
        bpy.context.scene.frame_set(f)
    assert_valid(obj)


def test_enable_again_in_same_session_driver_valid(addon, capfd):
    module = addon.__name__
    obj, left, right = pinned_rig()
    scene = bpy.context.scene
    addon_utils.disable(module, default_set=True)
    try:
        for f in range(1, 4):
            scene.frame_set(f)
    finally:
        addon_utils.enable(module, default_set=True)
    addon.shapedeform_addon.handlers.sync_scene()
    for f in (1, 5, 10):
        scene.frame_set(f)
    assert_valid(obj)


# -- a file from before the driver -----------------------------------------------------------

def test_old_file_gets_driver_back_on_load(addon, tmp_path, quiet):
    obj, left, right = pinned_rig()
    copy = duplicate([obj], obj)
    copy.location.x += 3.0
    bpy.context.view_layer.update()
    expected = {}
    for f in (1, 10):
        bpy.context.scene.frame_set(f)
        expected[f] = checks.evaluated_mesh_points(obj).copy()
    for o in (obj, copy):
        o.animation_data_clear()
    layer = bpy.context.view_layer.layer_collection.children[obj.shapedeform.handle_collection.name]
    layer.exclude = True
    path = str(tmp_path / "old.blend")
    copy_name = copy.name
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj, copy = bpy.data.objects["Grid"], bpy.data.objects[copy_name]
    for o in (obj, copy):
        assert_valid(o)
        assert targets(o) == expected_targets(obj), o.name
    for f in (10, 1, 10):
        bpy.context.scene.frame_set(f)
        np.testing.assert_allclose(checks.evaluated_mesh_points(obj), expected[f], atol=1e-5, err_msg=str(f))
        np.testing.assert_allclose(checks.evaluated_mesh_points(copy), expected[f], atol=1e-5, err_msg=str(f))


# -- undo ---------------------------------------------------------------------------------------

def watching(count, step=None):
    """The rig "Grid" after an undo step ``step`` ("undo", "redo" or None): its driver reads
    its ``count`` handles, and is valid."""
    if step is not None:
        assert getattr(bpy.ops.ed, step)() == {"FINISHED"}
    obj = bpy.data.objects["Grid"]
    assert targets(obj) == expected_targets(obj) and len(targets(obj)) == count
    assert_valid(obj)
    return obj


def test_undo_of_add_and_remove_handle_restores_driver(addon, quiet):
    obj, left, right = rig_with_two_handles()
    bpy.ops.ed.undo_push(message="two")
    checks.select_only(obj)
    assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.0, 0.0, 0.0])) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="three")
    watching(3)
    watching(2, "undo")
    obj = watching(3, "redo")
    checks.select_only(obj)
    first = obj.shapedeform.handles[0].object.name
    assert bpy.ops.shapedeform.remove_handle(handle=first) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="removed")
    watching(2)
    obj = watching(3, "undo")
    # moves still pose
    h = obj.shapedeform.handles[2].object
    before = checks.evaluated_mesh_points(obj).copy()
    h.location.y += 0.3
    bpy.context.view_layer.update()
    assert np.abs(checks.evaluated_mesh_points(obj) - before).max() > 0.1


def test_after_disable_enable_excluded_pins_keyed_amount_still_poses(addon, quiet):
    module = addon.__name__
    obj, left, right = pinned_rig()
    scene = bpy.context.scene
    pin = obj.shapedeform.handles[2].object
    assert pin.shapedeform.pin_kind == "OVERLAP"
    # fold: push right handle over the middle so the pin matters
    pin.shapedeform.in_front = -1.0
    pin.keyframe_insert("shapedeform.in_front", frame=1)
    pin.shapedeform.in_front = 1.0
    pin.keyframe_insert("shapedeform.in_front", frame=10)
    starch = obj.shapedeform.handles[3].object
    starch.shapedeform.stiffness = 0.0
    starch.keyframe_insert("shapedeform.stiffness", frame=1)
    starch.shapedeform.stiffness = 50.0
    starch.keyframe_insert("shapedeform.stiffness", frame=10)
    layer = bpy.context.view_layer.layer_collection.children[obj.shapedeform.handle_collection.name]
    layer.exclude = True
    expected = {}
    for f in (1, 10, 1, 10):
        scene.frame_set(f)
        expected[f] = checks.evaluated_mesh_points(obj).copy()
    assert np.abs(expected[10] - expected[1]).max() > 0.05
    addon_utils.disable(module, default_set=True)
    try:
        for f in (1, 4):
            scene.frame_set(f)
    finally:
        addon_utils.enable(module, default_set=True)
    addon.shapedeform_addon.handlers.sync_scene()
    for f in (10, 1, 10, 1):
        scene.frame_set(f)
        assert obj.shapedeform.status == ""
        np.testing.assert_allclose(checks.evaluated_mesh_points(obj), expected[f], atol=1e-5, err_msg=str(f))


# -- library link + override, append ------------------------------------------------------------

from test_everyday_operations import Rigged, character_collection, override_in_a_new_shot, evaluated  # noqa: E402


def save_character(tmp_path, with_pin=False):
    _, obj = character_collection(tmp_path)
    rig = Rigged(obj)
    if with_pin:
        checks.select_only(obj)
        assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.0, 0.0, 0.0]), kind="OVERLAP") == {"FINISHED"}
    library = str(tmp_path / "character.blend")
    bpy.ops.wm.save_as_mainfile(filepath=library)
    return library


def keyed_expectation(obj, handle):
    scene = bpy.context.scene
    handle.keyframe_insert("location", frame=1)
    handle.location.y += 0.5
    handle.keyframe_insert("location", frame=6)
    expected = {}
    for f in (1, 6):
        scene.frame_set(f)
        expected[f] = evaluated(obj).copy()
    assert np.abs(expected[6] - expected[1]).max() > 0.3
    return expected


def test_override_driver_targets_override_handles_and_excluded_collection(addon, tmp_path, quiet):
    library = save_character(tmp_path, with_pin=True)
    obj = override_in_a_new_shot(library)
    got = targets(obj)
    assert got is not None
    assert all(t[0].library is None for t in got), [(t[0].name, t[0].library) for t in got]
    assert got == expected_targets(obj)
    assert_valid(obj)
    handle = obj.shapedeform.handles[1].object
    expected = keyed_expectation(obj, handle)
    layer = bpy.context.view_layer.layer_collection
    # the handle collection: a child of the overridden Character collection
    character = layer.children["Character"]
    handles_layer = character.children[obj.shapedeform.handle_collection.name]
    handles_layer.exclude = True
    for f in (6, 1, 6):
        bpy.context.scene.frame_set(f)
        np.testing.assert_allclose(evaluated(obj), expected[f], atol=1e-5, err_msg=str(f))
    shot = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=shot)
    bpy.ops.wm.open_mainfile(filepath=shot)
    obj = next(o for o in bpy.context.scene.objects if o.name == "Grid")
    assert all(t[0].library is None for t in targets(obj))
    assert_valid(obj)
    for f in (6, 1, 6):
        bpy.context.scene.frame_set(f)
        np.testing.assert_allclose(evaluated(obj), expected[f], atol=1e-5, err_msg=str(f))


def test_appended_character_driver_targets_its_own_handles(addon, tmp_path, quiet):
    library = save_character(tmp_path, with_pin=True)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    with bpy.data.libraries.load(library, link=False) as (_, data):
        data.collections = ["Character"]
    bpy.context.scene.collection.children.link(data.collections[0])
    bpy.context.view_layer.update()
    obj = bpy.data.objects["Grid"]
    assert targets(obj) == expected_targets(obj)
    assert_valid(obj)
    # append a second copy
    with bpy.data.libraries.load(library, link=False) as (_, data):
        data.collections = ["Character"]
    bpy.context.scene.collection.children.link(data.collections[0])
    bpy.context.view_layer.update()
    second = next(o for o in data.collections[0].all_objects if o.type == "MESH" and o.shapedeform.is_bound)
    assert second != obj
    assert targets(second) == expected_targets(second)
    assert all(t[0].shapedeform.rig == second for t in targets(second))
    handle = second.shapedeform.handles[1].object
    expected = keyed_expectation(second, handle)
    bpy.context.view_layer.layer_collection.children[data.collections[0].name].children[
        second.shapedeform.handle_collection.name].exclude = True
    for f in (6, 1, 6):
        bpy.context.scene.frame_set(f)
        np.testing.assert_allclose(evaluated(second), expected[f], atol=1e-5, err_msg=str(f))


# -- handles parented to bones, constrained ------------------------------------------------------

def armature_driving(handle):
    """An armature in a collection "Armature" of the scene, whose bone ``handle`` is parented
    to, keyed to move it 0.5 between frames 1 and 10; returns the armature and its collection."""
    hidden_collection = bpy.data.collections.new("Armature")
    bpy.context.scene.collection.children.link(hidden_collection)
    arm_data = bpy.data.armatures.new("Rig")
    arm = bpy.data.objects.new("Rig", arm_data)
    hidden_collection.objects.link(arm)
    bpy.context.view_layer.update()
    with bpy.context.temp_override(active_object=arm, object=arm, selected_objects=[arm]):
        bpy.context.view_layer.objects.active = arm
        bpy.ops.object.mode_set(mode="EDIT")
        bone = arm_data.edit_bones.new("Ctrl")
        bone.head = handle.matrix_world.translation
        bone.tail = bone.head + type(bone.head)((0.0, 0.0, 0.3))
        bpy.ops.object.mode_set(mode="OBJECT")
    world = handle.matrix_world.copy()
    handle.parent = arm
    handle.parent_type = "BONE"
    handle.parent_bone = "Ctrl"
    bpy.context.view_layer.update()
    handle.matrix_world = world
    bpy.context.view_layer.update()
    pose_bone = arm.pose.bones["Ctrl"]
    pose_bone.location = (0, 0, 0)
    pose_bone.keyframe_insert("location", frame=1)
    pose_bone.location = (0.5, 0, 0)  # bone's local X
    pose_bone.keyframe_insert("location", frame=10)
    return arm, hidden_collection


@pytest.mark.parametrize("hide", ["hide_viewport", "exclude"])
def test_handle_parented_to_a_bone_of_a_hidden_armature(addon, hide, quiet):
    obj, left, right = rig_with_two_handles()
    scene = bpy.context.scene
    arm, rigcoll = armature_driving(right)
    expected = {}
    for f in (1, 10, 1, 10):
        scene.frame_set(f)
        expected[f] = checks.evaluated_mesh_points(obj).copy()
    assert np.abs(expected[10] - expected[1]).max() > 0.2
    if hide == "exclude":
        bpy.context.view_layer.layer_collection.children["Armature"].exclude = True
        bpy.context.view_layer.layer_collection.children[obj.shapedeform.handle_collection.name].exclude = True
    else:
        rigcoll.hide_viewport = True
        obj.shapedeform.handle_collection.hide_viewport = True
    for f in (10, 1, 10, 5, 1):
        scene.frame_set(f)
        if f in expected:
            np.testing.assert_allclose(checks.evaluated_mesh_points(obj), expected[f], atol=1e-5, err_msg=str(f))
    assert obj.shapedeform.status == ""


# -- a handle move evaluates the object once ---------------------------------------------------

@pytest.mark.parametrize("extra", ["follower", "pins", "excluded"])
def test_a_handle_move_evaluates_once(addon, extra):
    """Moving a handle evaluates the rigged object (and a copy following it) once, after the rig
    wrote the new pose, in the second pass Blender makes without callbacks for what the rig's
    handler wrote; not also in the pass that moved the handle (the modifier's Handles input made
    the handles its dependencies, so it was evaluated with the old pose first: 45 ms per move of
    a 200,000-vertex plane against 26)."""
    obj, left, right = rig_with_two_handles()
    watch = [obj]
    if extra == "follower":
        copy = duplicate([obj], obj)
        copy.location.x += 3.0
        watch.append(copy)
    elif extra == "pins":
        checks.select_only(obj)
        assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.0, 0.0, 0.0]), kind="OVERLAP") == {"FINISHED"}
        assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.5, 0.0, 0.0]), kind="STARCH") == {"FINISHED"}
    else:
        bpy.context.view_layer.layer_collection.children[obj.shapedeform.handle_collection.name].exclude = True
    bpy.context.view_layer.update()
    passes = []

    def seen(scene, depsgraph):
        passes.append({u.id.original.name: u.is_updated_geometry for u in depsgraph.updates})

    bpy.app.handlers.depsgraph_update_post.append(seen)
    try:
        for step in range(3):
            before = checks.evaluated_mesh_points(obj).copy()
            passes.clear()
            right.location.y += 0.1
            bpy.context.view_layer.update()
            assert len(passes) == 1, (step, passes)
            for o in watch:
                assert not passes[0].get(o.name), (step, o.name, passes)
            assert np.abs(checks.evaluated_mesh_points(obj) - before).max() > 0.02, step
            for o in watch[1:]:
                np.testing.assert_allclose(checks.evaluated_mesh_points(o), checks.evaluated_mesh_points(obj), atol=1e-6)
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(seen)


# -- workflows that replace or break the owner's animation data --------------------------------

def link_animation_from(source, targets_):
    for o in bpy.context.selected_objects:
        o.select_set(False)
    for o in targets_:
        o.select_set(True)
    source.select_set(True)
    bpy.context.view_layer.objects.active = source
    with view3d_override():
        assert bpy.ops.object.make_links_data(type="ANIMATION") == {"FINISHED"}
    bpy.context.view_layer.update()


def test_link_animation_data_onto_the_owner_keeps_handles_evaluated(addon, tmp_path, quiet):
    """Ctrl+L > Link Animation Data from an animated Empty onto the rigged object (to share a
    location animation): Render Animation with the rig's handle collection disabled in renders
    must still pose the keyed handle (README: the driver makes them evaluated there)."""
    import renders
    obj, left, right = rig_with_two_handles()
    scene = bpy.context.scene
    keyed_expectation(obj, right)
    renders.camera_over((0.5, -1.0), 3.0)
    source = bpy.data.objects.new("Animated", None)
    scene.collection.objects.link(source)
    source.location = obj.location
    source.keyframe_insert("location", frame=1)
    source.keyframe_insert("location", frame=6)
    link_animation_from(source, [obj])
    seen = renders.animation_frame(6, tmp_path, "shown")
    obj.shapedeform.handle_collection.hide_render = True
    hidden = renders.animation_frame(6, tmp_path, "hidden")
    assert np.abs(hidden - seen).max() == 0, f"{int((np.abs(hidden - seen).max(axis=2) > 0).sum())} pixels differ"


def test_link_animation_data_from_the_owner_to_a_plain_object(addon, capfd):
    """Ctrl+L > Link Animation Data from the rigged object to a prop: the prop gets the hidden
    driver on a property it does not have."""
    obj, left, right = rig_with_two_handles()
    prop = bpy.data.objects.new("Prop", None)
    bpy.context.scene.collection.objects.link(prop)
    link_animation_from(obj, [prop])
    capfd.readouterr()
    for f in range(1, 6):
        bpy.context.scene.frame_set(f)
    out, err = capfd.readouterr()
    warnings = (out + err).count("Invalid driver")
    assert watched(prop) is None, f"prop got the rig's driver on a property it lacks ({warnings} warnings over 5 frames)"


def test_a_handle_removed_from_python_leaves_a_valid_driver(addon, capfd):
    obj, left, right = rig_with_two_handles()
    third = checks.add_handle(obj, checks.world(obj, [0.0, 0.0, 0.0]))
    capfd.readouterr()
    bpy.data.objects.remove(third)
    for f in (1, 2, 3):
        bpy.context.scene.frame_set(f)
    right.location.y += 0.2
    bpy.context.view_layer.update()
    out, err = capfd.readouterr()
    assert "rror" not in out + err, out + err
    assert obj.shapedeform.status == ""
    assert_valid(obj)


# -- render animation and command-line bake with a bone-parented handle hidden ------------------

def test_render_animation_with_bone_parented_handle_disabled_in_renders(addon, tmp_path, quiet):
    import renders
    obj, left, right = rig_with_two_handles()
    _, rigcoll = armature_driving(right)
    renders.camera_over((0.5, -1.0), 3.0)
    seen = renders.animation_frame(10, tmp_path, "shown")
    rest = renders.animation_frame(1, tmp_path, "rest")
    assert np.abs(seen - rest).max() > 0.5
    rigcoll.hide_render = True
    obj.shapedeform.handle_collection.hide_render = True
    np.testing.assert_array_equal(renders.animation_frame(10, tmp_path, "hidden"), seen)


def test_cli_bake_with_bone_parented_handle_excluded(addon, tmp_path, quiet):
    obj, left, right = rig_with_two_handles()
    scene = bpy.context.scene
    _, rigcoll = armature_driving(right)
    expected = {}
    for f in (1, 10):
        scene.frame_set(f)
        expected[f] = checks.evaluated_mesh_points(obj).copy()
    bpy.context.view_layer.layer_collection.children["Armature"].exclude = True
    bpy.context.view_layer.layer_collection.children[obj.shapedeform.handle_collection.name].exclude = True
    scene.frame_set(1)
    path = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    assert addon.shapedeform_addon.cli.main(["bake", "--frames", "1-10"]) == 0
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Grid"]
    assert addon.shapedeform_addon.rig_format.is_baked(obj)
    for f in (10, 1):
        bpy.context.scene.frame_set(f)
        np.testing.assert_allclose(checks.evaluated_mesh_points(obj), expected[f], atol=1e-4, err_msg=str(f))


@pytest.mark.parametrize("how", ["instance", "collection_info"])
def test_instanced_character_in_shot_with_handles_disabled_in_renders(addon, how, tmp_path, quiet):
    import renders
    from test_everyday_operations import keyed_character, collection_info_host
    character, obj, posed = keyed_character(tmp_path)
    shot = bpy.data.scenes.new("Shot")
    if how == "instance":
        host = bpy.data.objects.new("Character Instance", None)
        host.instance_type, host.instance_collection = "COLLECTION", character
    else:
        host = collection_info_host(character)
    host.location.x = 0.0
    shot.collection.objects.link(host)
    bpy.context.window.scene = shot
    renders.camera_over((0.5, -1.0), 3.5)
    seen = renders.animation_frame(10, tmp_path, "shown")
    rest = renders.animation_frame(1, tmp_path, "rest")
    assert np.abs(seen - rest).max() > 0.5
    obj.shapedeform.handle_collection.hide_render = True
    obj.shapedeform.handle_collection.hide_viewport = True
    hidden = renders.animation_frame(10, tmp_path, "hidden")
    assert np.abs(hidden - seen).max() == 0, f"{int((np.abs(hidden - seen).max(axis=2) > 0).sum())} pixels differ"


def test_follower_after_its_owner_is_unbound(addon, tmp_path, capfd):
    original, left, right = rig_with_two_handles()
    copy = duplicate([original], original)
    copy.location.x += 3.0
    bpy.context.view_layer.update()
    checks.select_only(original)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    capfd.readouterr()
    for f in (1, 2, 3):
        bpy.context.scene.frame_set(f)
    out, err = capfd.readouterr()
    path = str(tmp_path / "f.blend")
    name = copy.name
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    copy = bpy.data.objects[name]
    fc = watched(copy)
    assert fc is None or fc.driver.is_valid, f"follower keeps an invalid driver: {targets(copy)}"
    assert "Invalid" not in out + err, out + err


def test_delete_globally_a_handle(addon, capfd):
    obj, left, right = rig_with_two_handles()
    third = checks.add_handle(obj, checks.world(obj, [0.0, 0.0, 0.0]))
    checks.select_only(third)
    with view3d_override():
        assert bpy.ops.object.delete(use_global=True) == {"FINISHED"}
    capfd.readouterr()
    for f in (1, 2, 3):
        bpy.context.scene.frame_set(f)
    out, err = capfd.readouterr()
    assert "rror" not in out + err, out + err
    assert_valid(obj)


def test_undo_of_unbind_restores_driver(addon, quiet):
    obj, left, right = rig_with_two_handles()
    bpy.ops.ed.undo_push(message="rig")
    checks.select_only(obj)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="unbound")
    assert bpy.data.objects["Grid"].animation_data is None
    assert bpy.ops.ed.undo() == {"FINISHED"}
    obj = bpy.data.objects["Grid"]
    assert targets(obj) == expected_targets(obj)
    assert_valid(obj)
