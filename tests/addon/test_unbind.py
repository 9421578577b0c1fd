# SPDX-License-Identifier: GPL-3.0-or-later
"""Unbinding gives the object back whatever state its rig is in: baked (issue 15, defect 8),
duplicated (defects 1 and 9), or with a grease-pencil keyframe deleted (defect 10); and what
Bind changed in data that duplicates share goes with the last rig of it."""

import bpy
import numpy as np
import pytest

import rig_checks as checks
from test_bake import rig
from test_rig_curve import curve_points, text_curve
from test_rig_grease_pencil import drawing_points
from test_rig_mesh import grid, puppet, rig_with_two_handles


def baked_curve_channels(obj):
    """Data paths of the F-curves on a curve's points (what a curve bake makes)."""
    from bpy_extras import anim_utils

    animation = obj.data.animation_data
    if animation is None or animation.action is None or animation.action_slot is None:
        return []
    bag = anim_utils.action_get_channelbag_for_slot(animation.action, animation.action_slot)
    return [c.data_path for c in bag.fcurves if c.data_path.startswith("splines[")] if bag else []


def unbind(obj):
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}


def make_mesh():
    obj = grid()
    return obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], lambda: checks.evaluated_mesh_points(obj)


def make_curve():
    obj = text_curve("I")
    rest = np.concatenate([p[:, :3] for p in curve_points(obj)])
    return obj, rest[np.argmin(rest[:, 1])], rest[np.argmax(rest[:, 1])], lambda: checks.evaluated_vertices(obj)


def make_grease_pencil():
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    rest = drawing_points(obj, evaluated=False)
    return obj, rest[np.argmin(rest[:, 2])], rest[np.argmax(rest[:, 2])], lambda: drawing_points(obj)


@pytest.mark.parametrize("make", [make_mesh, make_curve, make_grease_pencil])
def test_unbind_removes_the_bake_and_a_new_rig_is_live(addon, make):
    obj, first, second, evaluated = make()
    scene = bpy.context.scene
    rest = evaluated().copy()
    rig(obj, first, second, (0.4, 0.3, 0.0))
    assert addon.shapedeform_addon.bake.bake_objects([obj], 1, 6) == [obj]
    scene.frame_set(6)
    assert moved(evaluated(), rest) > 0.1  # the bake plays

    unbind(obj)
    assert "baked" not in obj.shapedeform and "baked_gp_frames" not in obj.shapedeform
    for frame in (1, 4, 6):  # the object is back to its own shape on every frame
        scene.frame_set(frame)
        assert evaluated().tobytes() == rest.tobytes(), f"frame {frame}"
    assert not obj.modifiers and obj.shapedeform.cage is None
    assert not any(a.get("shapedeform_bake") for a in bpy.data.actions)
    if obj.type == "MESH":
        assert obj.data.shape_keys is None
    elif obj.type == "CURVE":
        assert baked_curve_channels(obj) == []
    else:
        assert [[f.frame_number for f in layer.frames] for layer in obj.data.layers] == [[1]] * len(obj.data.layers)

    # A new rig on it is live: moving a handle moves the shape.
    scene.frame_set(1)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, first))
    handle = checks.add_handle(obj, checks.world(obj, second))
    handle.location.x += 0.3
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    assert moved(evaluated(), rest) > 0.1


def moved(points, rest):
    """How far the box round ``points`` (n, 3) is from the box round ``rest`` (m, 3): a filled
    curve's rig refines its fill, so the two need not have the same points."""
    return max(np.abs(points.min(axis=0) - rest.min(axis=0)).max(), np.abs(points.max(axis=0) - rest.max(axis=0)).max())


def _duplicate(original, linked):
    for o in bpy.context.selected_objects:
        o.select_set(False)
    original.select_set(True)
    bpy.context.view_layer.objects.active = original
    assert bpy.ops.object.duplicate(linked=linked) == {"FINISHED"}  # the handles are not selected
    copy = bpy.context.active_object
    assert copy is not original
    return copy


@pytest.mark.parametrize("linked", [False, True], ids=["Shift+D", "Alt+D"])
def test_a_duplicate_follows_the_rig_and_unbinding_it_leaves_the_original_alone(addon, linked):
    original, left, right = rig_with_two_handles()
    rest = checks.mesh_points(original).copy()
    collection = original.shapedeform.handle_collection
    names = {o.name for o in bpy.data.objects}
    copy = _duplicate(original, linked)
    assert (copy.data == original.data) == linked
    copy.location.x += 3.0  # moved away, it still shows the rig's pose in its own space
    right.location.y += 0.3
    bpy.context.view_layer.update()
    np.testing.assert_allclose(checks.evaluated_mesh_points(copy), checks.evaluated_mesh_points(original), atol=1e-6)
    assert np.abs(checks.evaluated_mesh_points(copy) - rest).max() > 0.2

    unbind(copy)
    assert not copy.shapedeform.is_bound and len(copy.shapedeform.handles) == 0 and not copy.modifiers
    assert copy.animation_data is None  # nor the driver that kept the rig's handles evaluated
    assert checks.evaluated_mesh_points(copy).tobytes() == rest.tobytes()
    # The original keeps its handles, cage, collection and a working rig.
    assert {o.name for o in bpy.data.objects} == names | {copy.name}
    assert [item.object for item in original.shapedeform.handles] == [left, right]
    assert collection.name in bpy.data.collections
    assert set(collection.objects) == {left, right, original.shapedeform.cage}
    _assert_still_follows(original, right, rest)

    # Unbinding the original afterwards still removes its own handles, cage and collection.
    unbind(original)
    assert original.animation_data is None
    assert {o.name for o in bpy.data.objects} == {original.name, copy.name}
    assert not any("Handles" in c.name for c in bpy.data.collections)
    assert checks.mesh_points(original).tobytes() == rest.tobytes()


@pytest.mark.parametrize("linked", [False, True], ids=["Shift+D", "Alt+D"])
def test_a_duplicate_made_with_its_handles_gets_a_rig_of_its_own(addon, linked, tmp_path, quiet):
    """Duplicating a rigged object together with its handles (and a pin) gives the copy a rig
    of its own, as duplicating a mesh with its armature does: each object's handles move only
    it, through save and reopen, and unbinding the copy removes its handles, cage and collection
    and leaves the original's (the copied handles moved nothing, and stayed behind)."""
    original, left, right = rig_with_two_handles()
    bpy.context.view_layer.objects.active = original
    assert bpy.ops.shapedeform.add_handle(location=checks.world(original, [0.0, 0.0, 0.0]), kind="OVERLAP") == {"FINISHED"}
    pin = original.shapedeform.handles[-1].object
    for o in bpy.context.selected_objects:
        o.select_set(False)
    for o in (original, left, right, pin):
        o.select_set(True)
    bpy.context.view_layer.objects.active = original
    assert bpy.ops.object.duplicate(linked=linked) == {"FINISHED"}
    copy = bpy.context.active_object
    copy.location.x += 3.0
    bpy.context.view_layer.update()
    rig_format = addon.shapedeform_addon.rig_format
    assert rig_format.is_owner(copy) and rig_format.is_owner(original)
    handles = [item.object for item in copy.shapedeform.handles]
    assert len(handles) == 3 and not {left, right, pin} & set(handles)
    assert copy.shapedeform.cage not in (None, original.shapedeform.cage)
    assert copy.shapedeform.handle_collection != original.shapedeform.handle_collection
    assert set(copy.shapedeform.handle_collection.objects) == {*handles, copy.shapedeform.cage}
    assert handles[2].parent == copy.shapedeform.cage

    def moves(handle, obj, other):
        before = checks.evaluated_mesh_points(obj).copy(), checks.evaluated_mesh_points(other).copy()
        handle.location.y += 0.3
        bpy.context.view_layer.update()
        assert obj.shapedeform.status == ""
        assert np.abs(checks.evaluated_mesh_points(obj) - before[0]).max() > 0.2
        np.testing.assert_array_equal(checks.evaluated_mesh_points(other), before[1])

    moves(handles[1], copy, original)
    moves(right, original, copy)
    path = str(tmp_path / "two.blend")
    names = original.name, copy.name
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    original, copy = (bpy.data.objects[name] for name in names)
    moves(copy.shapedeform.handles[1].object, copy, original)
    moves(original.shapedeform.handles[1].object, original, copy)

    names = {o.name for o in bpy.data.objects} - {o.name for o in (*copy.shapedeform.handle_collection.objects, copy)}
    unbind(copy)
    assert {o.name for o in bpy.data.objects} == names | {copy.name}
    moves(original.shapedeform.handles[0].object, original, copy)


def test_a_duplicate_made_with_a_pin_but_no_handle_follows_the_rig(addon, quiet):
    """Duplicating a rigged object with one of its pins and none of its handles makes a copy
    that follows the rig, as a plain Shift+D does (it became a rig of its own with no handle and
    snapped to its rest shape on the next frame, 0.8 off here); the copied pin is a copy of a
    pin, as one duplicated alone: its rig's list does not name it, and it moves nothing."""
    original, left, right = rig_with_two_handles()
    checks.select_only(original)
    assert bpy.ops.shapedeform.add_handle(location=checks.world(original, [0.0, 0.0, 0.0]),
                                          kind="STARCH") == {"FINISHED"}
    pin = original.shapedeform.handles[-1].object
    right.location.y += 0.8
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(original).copy()
    checks.select_only(original)
    pin.select_set(True)
    assert bpy.ops.object.duplicate() == {"FINISHED"}
    copy = bpy.context.active_object
    pin_copy = next(o for o in bpy.context.selected_objects if o.type == "EMPTY")
    bpy.context.scene.frame_set(2)
    off = float(np.abs(checks.evaluated_mesh_points(copy) - posed).max())
    assert off < 1e-5, f"the copy is {off:.3g} off the rig's pose"
    rig_format = addon.shapedeform_addon.rig_format
    assert rig_format.is_follower(copy) and copy.shapedeform.cage.shapedeform.rig == original
    assert pin_copy.shapedeform.rig == original
    assert [item.object for item in original.shapedeform.handles] == [left, right, pin]
    _assert_still_follows(copy, right, checks.mesh_points(original))


def test_a_handle_added_in_edit_mode_on_a_duplicate_holds_the_selected_point(addon):
    """Edit Mode on a duplicate that follows the rig, a point selected, Add Handle: the handle
    goes to the rig (its owner's), on the point the duplicate shares with it, and moving it
    moves that point of both (it was placed at the duplicate's world position, over another
    part of the owner, and moved that part)."""
    original, _, _ = rig_with_two_handles()
    rest = checks.mesh_points(original).copy()
    copy = _duplicate(original, False)
    copy.location.x += 4.0
    chosen = int(np.argmin(np.linalg.norm(rest[:, :2] - [0.0, -0.5], axis=1)))  # the bottom edge's middle
    mesh = copy.data
    for elements in (mesh.polygons, mesh.edges):  # in bulk: element by element has crashed Blender
        elements.foreach_set("select", np.zeros(len(elements), dtype=bool))
    mesh.vertices.foreach_set("select", np.arange(len(mesh.vertices)) == chosen)
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    handle = original.shapedeform.handles[-1].object
    before = checks.evaluated_mesh_points(copy).copy()
    handle.location.y -= 0.5
    bpy.context.view_layer.update()
    moved = np.linalg.norm(checks.evaluated_mesh_points(copy) - before, axis=1)
    assert moved[chosen] == pytest.approx(0.5, abs=1e-4)
    np.testing.assert_allclose(checks.evaluated_mesh_points(original), checks.evaluated_mesh_points(copy), atol=1e-6)


def test_a_handle_added_in_object_mode_on_a_duplicate_holds_the_point_under_the_cursor(addon):
    """Object Mode on a duplicate that follows the rig, the 3D cursor on it: the handle holds
    the point of the duplicate under the cursor (it was placed in the owner's space, off the
    shape, holding whatever part of the owner was nearest)."""
    original, _, _ = rig_with_two_handles()
    rest = checks.mesh_points(original).copy()
    copy = _duplicate(original, False)
    copy.location.x += 4.0
    bpy.context.view_layer.update()
    chosen = int(np.argmin(np.linalg.norm(rest[:, :2] - [0.0, -0.5], axis=1)))  # the bottom edge's middle
    bpy.context.scene.cursor.location = checks.world(copy, rest[chosen])
    bpy.context.view_layer.objects.active = copy
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    handle = original.shapedeform.handles[-1].object
    np.testing.assert_allclose(handle.matrix_world.translation, checks.world(original, rest[chosen]), atol=1e-5)
    before = checks.evaluated_mesh_points(copy).copy()
    handle.location.y -= 0.5
    bpy.context.view_layer.update()
    moved = np.linalg.norm(checks.evaluated_mesh_points(copy) - before, axis=1)
    assert moved[chosen] == pytest.approx(0.5, abs=1e-4)


def _world_points(obj):
    bpy.context.view_layer.update()
    matrix = np.array(obj.matrix_world)
    return checks.evaluated_mesh_points(obj) @ matrix[:3, :3].T + matrix[:3, 3]


@pytest.mark.parametrize("applied, transform", [("copy", "scale"), ("original", "scale"), ("copy", "location"),
                                                ("copy", "rotation")])
def test_apply_transform_on_a_duplicate_or_its_original_keeps_both_where_they_are(addon, applied, transform):
    """Apply Location/Rotation/Scale keeps a deformed object where it is; a Shift+D duplicate
    that follows the rig too, whichever of the two it is applied to (the duplicate jumped by up
    to 0.94 and its bend grew: both read the rig through the original's data space)."""
    original, _, right = rig_with_two_handles()
    right.location.y += 0.6
    bpy.context.view_layer.update()
    copy = _duplicate(original, False)
    copy.location.x += 4.0
    target = copy if applied == "copy" else original
    setattr(target, "scale" if transform == "scale" else "rotation_euler" if transform == "rotation" else "location",
            (2.0, 1.5, 1.0) if transform == "scale" else (0.0, 0.0, 0.4) if transform == "rotation"
            else tuple(target.location))
    before = {o.name: _world_points(o) for o in (original, copy)}
    checks.select_only(target)
    assert bpy.ops.object.transform_apply(location=transform == "location", rotation=transform == "rotation",
                                          scale=transform == "scale") == {"FINISHED"}
    for o in (original, copy):
        np.testing.assert_allclose(_world_points(o), before[o.name], atol=1e-5, err_msg=o.name)
    right.location.y -= 0.3  # and both still follow the rig, each in its own place
    bpy.context.view_layer.update()
    moved = {o.name: np.abs(_world_points(o) - before[o.name]).max() for o in (original, copy)}
    assert moved[original.name] > 0.1 and moved[copy.name] > 0.1


def test_a_duplicate_from_an_older_version_gets_its_own_cage_when_the_file_opens(addon):
    """Older versions had a follower read the original's cage in the original's space: on
    opening (the same pass as enabling the extension), it gets a cage of its own and shows the
    same pose."""
    shapedeform = addon.shapedeform_addon
    original, _, right = rig_with_two_handles()
    right.location.y += 0.4
    copy = _duplicate(original, False)
    copy.location.x += 4.0
    shown = _world_points(copy)
    own = copy.shapedeform.cage
    assert own != original.shapedeform.cage and own.parent == copy and own.data == original.shapedeform.cage.data
    # As an older version left it:
    copy.shapedeform.cage = original.shapedeform.cage
    shapedeform.rig_format.point_inputs(copy, {shapedeform.nodes.CAGE_INPUT: original.shapedeform.cage})
    bpy.data.objects.remove(own)
    shapedeform.handlers.sync_scene()
    assert copy.shapedeform.cage not in (None, original.shapedeform.cage)
    np.testing.assert_allclose(_world_points(copy), shown, atol=1e-5)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"} and copy.shapedeform.cage is None  # the active copy
    bpy.context.view_layer.objects.active = original
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert not any(o.shapedeform.rig == original for o in bpy.data.objects)


def test_deleting_a_duplicate_that_follows_a_rig_leaves_nothing_behind(addon, tmp_path):
    """Its cage is in no collection and used by it alone: deleted with it, it is not saved."""
    original, _, _ = rig_with_two_handles()
    copy = _duplicate(original, False)
    bpy.context.view_layer.update()
    cage_name = copy.shapedeform.cage.name
    assert not copy.shapedeform.cage.users_collection
    checks.select_only(copy)
    assert bpy.ops.object.delete() == {"FINISHED"}
    path = str(tmp_path / "deleted.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    assert cage_name not in bpy.data.objects
    assert [o.name for o in bpy.data.objects if o.type == "MESH" and o.shapedeform.rig is not None] == ["Grid Cage"]


def test_a_set_duplicated_with_its_follower_follows_the_copied_rig(addon):
    """Owner, handles and a duplicate following them, duplicated together: the copies make a
    rig of their own and the copied follower follows it (it kept following the original's)."""
    original, left, right = rig_with_two_handles()
    follower = _duplicate(original, False)
    follower.location.y += 3.0
    bpy.context.view_layer.update()
    for o in bpy.context.selected_objects:
        o.select_set(False)
    for o in (original, left, right, follower):
        o.select_set(True)
    bpy.context.view_layer.objects.active = original
    assert bpy.ops.object.duplicate() == {"FINISHED"}
    copies = list(bpy.context.selected_objects)
    bpy.context.view_layer.update()
    owner = next(o for o in copies if o.type == "MESH" and addon.shapedeform_addon.rig_format.is_owner(o))
    copied_follower = next(o for o in copies if o.type == "MESH" and o != owner)
    assert addon.shapedeform_addon.rig_format.owner_of(copied_follower) == owner
    shapedeform = addon.shapedeform_addon
    watched = copied_follower.animation_data.drivers.find(shapedeform.rig_format.HANDLES_WATCHED)
    assert [v.targets[0].id for v in watched.driver.variables] == [i.object for i in owner.shapedeform.handles]
    handle = owner.shapedeform.handles[-1].object
    before = checks.evaluated_mesh_points(copied_follower).copy()
    handle.location.y += 0.5
    bpy.context.view_layer.update()
    np.testing.assert_allclose(checks.evaluated_mesh_points(copied_follower), checks.evaluated_mesh_points(owner),
                               atol=1e-6)
    assert np.abs(checks.evaluated_mesh_points(copied_follower) - before).max() > 0.1


def test_a_duplicate_moved_to_another_scene_plays_its_rigs_animation_there(addon):
    """The copy alone in a shot scene: its rig's keyed handle poses it on every frame there
    (it showed the last pose written in the first scene), and the shot's bake finds the rig."""
    original, _, right = rig_with_two_handles()
    first = bpy.context.scene
    right.keyframe_insert("location", frame=1)
    right.location.y += 0.6
    right.keyframe_insert("location", frame=10)
    first.frame_set(1)
    copy = _duplicate(original, False)
    shot = bpy.data.scenes.new("Shot")
    shot.collection.objects.link(copy)
    first.collection.objects.unlink(copy)
    bpy.context.window.scene = shot
    shapedeform = addon.shapedeform_addon
    assert shapedeform.rig_format.owners(shot) == [original]
    tops = []
    for frame in (1, 10):
        shot.frame_set(frame)
        tops.append(checks.evaluated_mesh_points(copy)[:, 1].max())
    assert tops[1] - tops[0] == pytest.approx(0.6, abs=0.05)


def _assert_still_follows(original, handle, rest):
    """The original's rig is live: moving its right handle up moves the grid's right tip."""
    handle.location.y += 0.4
    bpy.context.view_layer.update()
    assert original.shapedeform.status == ""
    tip = np.argmin(np.linalg.norm(rest[:, :2] - [1.0, 0.0], axis=1))
    assert checks.evaluated_mesh_points(original)[tip, 1] == pytest.approx(handle.location.y, abs=1e-5)


def test_a_grease_pencil_rig_keeps_working_when_a_keyframe_is_deleted(addon):
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    obj.name = "Monkey"
    lines = obj.data.layers["Lines"]
    rest = drawing_points(obj, evaluated=False)
    lines_rest = checks.drawing_points(lines.current_frame().drawing).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, rest[np.argmin(rest[:, 2])]))
    handle = checks.add_handle(obj, checks.world(obj, rest[np.argmax(rest[:, 2])]))
    handle.location.x += 0.3
    bpy.context.view_layer.update()
    assert np.abs(drawing_points(obj) - rest).max() > 0.1

    obj.data.layers["Fills"].frames.remove(1)  # the animator deletes a keyframe the rig was bound on
    handle.location.x += 0.1
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    assert np.abs(checks.evaluated_drawing_points(obj, "Lines") - lines_rest).max() > 0.3

    unbind(obj)
    assert not obj.shapedeform.is_bound and not obj.modifiers
    assert not any(key in obj.shapedeform for key in ("graph_points", "plane"))
    assert [o.name for o in bpy.data.objects] == ["Monkey"]
    assert not any("Handles" in c.name for c in bpy.data.collections)
    assert checks.drawing_points(lines.current_frame().drawing).tobytes() == lines_rest.tobytes()


@pytest.mark.parametrize("shared", [False, True], ids=["own quad", "quad shared with a linked copy"])
def test_an_image_plane_unbound_after_apply_gets_its_quad_back_where_its_picture_is(addon, tmp_path, shared):
    """Apply Rotation & Scale on a bound image plane changes its cut-out; the quad it gets back
    on unbind gets the same change (found by the state-machine test, seed 4)."""
    from test_rig_image_plane import import_picture

    obj, _ = import_picture(tmp_path)
    quad = obj.data
    quad_rest = checks.mesh_points(obj).copy()
    twin = None
    if shared:  # an unbound linked duplicate keeps showing the quad as it was
        twin = _duplicate(obj, linked=True)
        bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    obj.rotation_euler = (0.4, 0.0, 0.3)
    obj.scale = (1.5, 1.5, 1.5)
    bpy.context.view_layer.update()
    to_world = lambda o, p: p @ np.array(o.matrix_world)[:3, :3].T + np.array(o.matrix_world)[:3, 3]  # noqa: E731
    cutout = to_world(obj, checks.mesh_points(obj))
    for o in bpy.context.selected_objects:
        o.select_set(False)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.object.transform_apply(location=False, rotation=True, scale=True) == {"FINISHED"}
    np.testing.assert_allclose(to_world(obj, checks.mesh_points(obj)), cutout, atol=1e-5)

    unbind(obj)
    corners = to_world(obj, checks.mesh_points(obj))
    assert np.all(cutout.min(axis=0) > corners.min(axis=0) - 1e-5)
    assert np.all(cutout.max(axis=0) < corners.max(axis=0) + 1e-5)
    assert (obj.data == quad) != shared
    if shared:
        assert twin.data == quad and checks.mesh_points(twin).tobytes() == quad_rest.tobytes()


@pytest.mark.parametrize("linked", [False, True], ids=["Shift+D", "Alt+D"])
def test_a_duplicate_whose_rig_was_unbound_unbinds_without_a_false_warning(addon, capfd, linked):
    """A duplicate left bound with no cage, as unbinding its owner left it before it released
    its duplicates (files saved then still hold such): unbinding it must not go the way of an
    older version's rig and warn that its rest shape is lost (it never was written). Found by
    the state-machine test, seeds 21 and 22 with 1,500 steps."""
    original, left, right = rig_with_two_handles()
    rest = checks.mesh_points(original).copy()
    copy = _duplicate(original, linked)
    right.location.y += 0.3
    bpy.context.view_layer.update()
    bpy.data.objects.remove(copy.shapedeform.cage)  # as unbinding the owner left it
    unbind(original)
    assert copy.shapedeform.is_bound and copy.shapedeform.cage is None
    assert checks.evaluated_mesh_points(copy).tobytes() == rest.tobytes()  # no cage: it shows its data
    bpy.context.view_layer.objects.active = copy
    with pytest.raises(RuntimeError, match="lost its cage .*its rig unbound"):
        bpy.ops.shapedeform.bake(frame_start=1, frame_end=2)
    capfd.readouterr()
    unbind(copy)
    out = capfd.readouterr()
    assert "could not give back" not in out.out + out.err
    assert not copy.shapedeform.is_bound and not copy.modifiers
    assert checks.mesh_points(copy).tobytes() == rest.tobytes()


def test_unbinding_an_image_plane_says_its_cut_outs_shape_keys_go(addon, tmp_path, capfd):
    """Shape keys added to a bound image plane live on its cut-out, which Unbind replaces with
    the picture's quad: the warning names them (they went without a word)."""
    from test_rig_image_plane import import_picture

    obj, _ = import_picture(tmp_path)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    obj.shape_key_add(name="Basis")
    obj.shape_key_add(name="Squash").value = 0.5
    capfd.readouterr()
    unbind(obj)
    out = capfd.readouterr()
    assert "shape keys of its cut-out" in out.out + out.err


# -- what Bind leaves in data that duplicates share -------------------------------------------

class Rigged:
    """A shape of one kind bound with two handles, and what its Bind leaves in its data.

    ``marks(data)`` names what Bind changed on the data (a curve's Path Animation turned off and
    its mark, a puppet's hidden islands, the attribute of a drawing's rigged layers); ``shown``
    and ``own`` read an object's evaluated points and its data's."""

    def __init__(self, kind):
        self.kind = kind
        if kind == "curve":
            bpy.ops.curve.primitive_bezier_circle_add(radius=1.0)  # Path Animation on
            self.obj = bpy.context.active_object
            ends = [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]
        elif kind == "puppet":
            self.obj, _ = puppet()  # its arm's island overlaps its body's
            ends = [0.0, 0.5, 0.0], [3.0, 0.5, 0.0]
        else:
            bpy.ops.object.grease_pencil_add(type="MONKEY")
            self.obj = bpy.context.active_object
            self.obj.shapedeform.layers = "Lines"
            lines = checks.drawing_points(self.obj.data.layers["Lines"].current_frame().drawing)
            ends = lines[np.argmin(lines[:, 2])], lines[np.argmax(lines[:, 2])]
        assert not self.marks(self.obj.data)
        self.handles = checks.bind_with_handles(self.obj, *ends)
        assert self.marks(self.obj.data)

    def marks(self, data):
        if self.kind == "curve":
            return (set() if data.use_path else {"Path Animation off"}) | ({"shapedeform_path_off"} & set(data.keys()))
        return {a.name for a in data.attributes if a.name.startswith((".sd_island", "sd_rigged"))}

    def shown(self, obj):
        if self.kind == "curve":
            return checks.evaluated_curve_points(obj)
        if self.kind == "puppet":
            return checks.evaluated_mesh_points(obj)
        return checks.evaluated_drawing_points(obj)

    def own(self, obj):
        if self.kind == "curve":
            return np.concatenate(curve_points(obj))
        if self.kind == "puppet":
            return checks.mesh_points(obj)
        return drawing_points(obj, evaluated=False)

    def assert_released(self, obj):
        """``obj`` is a plain object again: unbound, nothing of a rig on it, showing its data."""
        settings = obj.shapedeform
        assert not settings.is_bound and settings.cage is None and not obj.modifiers, f"'{obj.name}' is still rigged"
        assert obj.animation_data is None  # nor the driver that kept the rig's handles evaluated
        assert self.shown(obj).tobytes() == self.own(obj).tobytes()

    def assert_given_back(self, obj):
        """:meth:`assert_released`, and its data as before Bind."""
        self.assert_released(obj)
        assert not self.marks(obj.data), f"Bind's {self.marks(obj.data)} left on '{obj.name}''s data"


KINDS = ["curve", "puppet", "grease pencil"]


@pytest.mark.parametrize("linked", [False, True], ids=["Shift+D", "Alt+D"])
@pytest.mark.parametrize("kind", KINDS)
def test_unbinding_the_original_releases_its_duplicates_and_gives_their_data_back(addon, kind, linked, quiet):
    """Unbind on the original of duplicates that follow its rig: they stop following, as Stop
    Following does, and every data block is as before Bind. (Each duplicate was left bound
    with no cage; an Alt+D curve's Path Animation stayed off and a linked puppet's islands on
    its mesh, as the duplicate still counted as a rig of the data; a Shift+D copy kept them in
    its own data.)"""
    rigged = Rigged(kind)
    original = rigged.obj
    copy = _duplicate(original, linked)
    copy.location.x += 3.0
    rigged.handles[1].location.x += 0.3
    bpy.context.view_layer.update()
    assert np.abs(rigged.shown(copy) - rigged.own(copy)).max() > 0.1  # it follows the rig

    unbind(original)
    for obj in (original, copy):
        rigged.assert_given_back(obj)
    assert {o.name for o in bpy.data.objects} == {original.name, copy.name}


@pytest.mark.parametrize("linked", [False, True], ids=["Shift+D", "Alt+D"])
@pytest.mark.parametrize("kind", KINDS)
def test_stop_following_gives_back_what_bind_left_in_the_duplicates_own_data_only(addon, kind, linked, quiet):
    """Stop Following (Unbind on a duplicate) takes from a copy's own data what Bind left in
    it (a Shift+D drawing kept its rigged layers' attribute), and leaves data the original's
    rig still deforms as it is."""
    rigged = Rigged(kind)
    original = rigged.obj
    copy = _duplicate(original, linked)
    marks = rigged.marks(original.data)
    unbind(copy)
    if linked:
        rigged.assert_released(copy)
    else:
        rigged.assert_given_back(copy)
    assert rigged.marks(original.data) == marks
    unbind(original)
    rigged.assert_given_back(original)


@pytest.mark.parametrize("kind", KINDS)
def test_unbinding_a_linked_duplicates_own_rig_leaves_the_originals_in_their_data(addon, kind, quiet):
    """Alt+D with the handles gives the copy a rig of its own on the original's data: unbinding
    it leaves what the original's rig needs there (the drawing lost the attribute of its rigged
    layers, and the original's rig then deformed every layer)."""
    rigged = Rigged(kind)
    original = rigged.obj
    checks.select_only(original)
    for handle in rigged.handles:
        handle.select_set(True)
    assert bpy.ops.object.duplicate(linked=True) == {"FINISHED"}
    copy = bpy.context.active_object
    assert addon.shapedeform_addon.rig_format.is_owner(copy) and copy.data == original.data
    marks = rigged.marks(original.data)
    unbind(copy)
    assert rigged.marks(original.data) == marks
    if kind == "grease pencil":
        fills = checks.drawing_points(original.data.layers["Fills"].current_frame().drawing).copy()
        rigged.handles[1].location.x += 0.3
        bpy.context.view_layer.update()
        assert checks.evaluated_drawing_points(original, "Fills").tobytes() == fills.tobytes()
    unbind(original)
    rigged.assert_given_back(original)


def test_the_last_unbind_of_a_scene_turns_lock_interface_off_again(addon):
    """Bind turns Render > Lock Interface on (frame handlers pose rigs during renders); it
    stayed on after every rig was unbound. Off again with the scene's last rig, and a lock the
    user had turned on stays."""
    scene = bpy.context.scene
    scene.render.use_lock_interface = False
    first, second = grid("First"), grid("Second")
    for obj in (first, second):
        checks.select_only(obj)
        assert bpy.ops.shapedeform.bind() == {"FINISHED"}
        assert scene.render.use_lock_interface
    unbind(first)
    assert scene.render.use_lock_interface  # Second's renders still pose it
    unbind(second)
    assert not scene.render.use_lock_interface
    assert not any(key.startswith("shapedeform") for key in scene.keys())  # the mark went with it

    scene.render.use_lock_interface = True  # the user's own
    checks.select_only(first)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    unbind(first)
    assert scene.render.use_lock_interface
    assert not any(key.startswith("shapedeform") for key in scene.keys())
