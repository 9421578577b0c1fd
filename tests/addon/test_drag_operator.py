# SPDX-License-Identifier: GPL-3.0-or-later
"""The drag operator: its per-event functions, and ``modal()`` driven by stand-in events.

``invoke`` needs a window, so the tests build a stand-in viewport (an orthographic top view
of a 200 x 100 pixel region) that ``bpy_extras.view3d_utils`` accepts, and call the operator's
``modal`` with stand-in events.
"""

from types import SimpleNamespace

import bpy
import numpy as np
import pytest
from bpy_extras import anim_utils, view3d_utils
from mathutils import Matrix

import rig_checks as checks
from test_rig_mesh import grid, rig_with_two_handles


def viewport():
    """Top orthographic view: world x in [-4, 4] and y in [-2, 2] fill the region."""
    view = Matrix.Translation((0.0, 0.0, -10.0))
    projection = Matrix.Diagonal((0.25, 0.5, -0.01, 1.0))
    region = SimpleNamespace(x=0, y=0, width=200, height=100, type="WINDOW")
    region_3d = SimpleNamespace(view_matrix=view, perspective_matrix=projection @ view,
                                is_perspective=False, view_perspective="ORTHO")
    return region, region_3d


def event(kind, value, world=None, ctrl=False, view=None):
    region, region_3d = view or viewport()
    x = y = 0
    if world is not None:
        x, y = view3d_utils.location_3d_to_region_2d(region, region_3d, world)
    return SimpleNamespace(type=kind, value=value, mouse_x=x, mouse_y=y, ctrl=ctrl)


def operator_stand_in(addon, obj):
    drag = addon.shapedeform_addon.drag
    reports = []
    session = drag.DragSession(obj, *viewport())
    op = SimpleNamespace(session=session, report=lambda kind, text: reports.append(text))
    return drag.SHAPEDEFORM_OT_drag.modal, op, reports


def dragged_by_script(addon, obj, handle, offset):
    """Grab ``handle`` of ``obj``'s rig with a ray from above, as a script drives the drag, and
    move it by ``offset`` (3,); returns the drag's state, to confirm or cancel."""
    drag = addon.shapedeform_addon.drag
    start = np.array(handle.matrix_world.translation)
    ray = lambda point: (np.array([point[0], point[1], 5.0]), np.array([0.0, 0.0, -1.0]))  # noqa: E731
    state = drag.begin(bpy.context, obj, ray(start))
    drag.move(bpy.context, state, ray(start + np.asarray(offset)))
    return state


def test_modal_drag_follows_the_mouse_and_confirms(addon):
    obj, left, right = rig_with_two_handles()
    modal, op, reports = operator_stand_in(addon, obj)
    rest = checks.mesh_points(obj).copy()
    start = np.array(right.matrix_world.translation)
    # Grab a little off the handle: the nearest handle is grabbed and keeps its offset.
    grab = start + np.array([0.05, -0.05, 0.0])
    assert modal(op, bpy.context, event("LEFTMOUSE", "PRESS", grab)) == {"RUNNING_MODAL"}
    assert op.session.state.handle == right
    assert "confirm" in op.session.header()
    assert modal(op, bpy.context, event("MOUSEMOVE", "NOTHING", grab + np.array([0.0, 0.5, 0.0]))) \
        == {"RUNNING_MODAL"}
    np.testing.assert_allclose(right.matrix_world.translation, start + np.array([0, 0.5, 0]), atol=1e-5)
    posed = checks.evaluated_mesh_points(obj).copy()
    tip = np.argmin(np.linalg.norm(rest - (start - np.array(obj.location)), axis=1))
    assert posed[tip, 1] - rest[tip, 1] > 0.45  # the shape followed live
    assert modal(op, bpy.context, event("RET", "PRESS")) == {"FINISHED"}
    assert op.session.state is None
    np.testing.assert_allclose(right.matrix_world.translation, start + np.array([0, 0.5, 0]), atol=1e-5)
    assert checks.evaluated_mesh_points(obj).tobytes() == posed.tobytes()
    assert reports == []


def test_a_drag_grabs_the_nearest_handle_never_a_pin(addon):
    """An overlap pin nearer the click than any handle: the handle is grabbed (the pin was, and
    left off the shape it rides on, the shape unmoved)."""
    obj, left, right = rig_with_two_handles()
    bpy.context.view_layer.objects.active = obj
    near = np.array(right.matrix_world.translation) + np.array([-0.15, 0.0, 0.0])
    assert bpy.ops.shapedeform.add_handle(location=tuple(near), kind="OVERLAP") == {"FINISHED"}
    pin = obj.shapedeform.handles[-1].object
    bpy.context.view_layer.update()
    modal, op, _ = operator_stand_in(addon, obj)
    click = np.array(pin.matrix_world.translation) + np.array([0.01, 0.0, 0.0])
    modal(op, bpy.context, event("LEFTMOUSE", "PRESS", click))
    assert op.session.state.handle == right
    modal(op, bpy.context, event("RIGHTMOUSE", "PRESS"))


def test_modal_cancel_restores_handle_and_shape_exactly(addon):
    obj, left, right = rig_with_two_handles()
    right.location.y += 0.2
    bpy.context.view_layer.update()
    before_points = checks.evaluated_mesh_points(obj).copy()
    rest = checks.mesh_points(obj).copy()
    before_location = tuple(right.location)
    for cancel in ("ESC", "RIGHTMOUSE"):
        modal, op, _ = operator_stand_in(addon, obj)
        start = np.array(right.matrix_world.translation)
        modal(op, bpy.context, event("LEFTMOUSE", "PRESS", start))
        modal(op, bpy.context, event("MOUSEMOVE", "NOTHING", start + np.array([0.3, -0.4, 0.0])))
        assert np.abs(checks.evaluated_mesh_points(obj) - before_points).max() > 0.1
        assert modal(op, bpy.context, event(cancel, "PRESS")) == {"CANCELLED"}
        assert tuple(right.location) == before_location
        assert checks.evaluated_mesh_points(obj).tobytes() == before_points.tobytes()
        assert checks.mesh_points(obj).tobytes() == rest.tobytes()  # the mesh itself never moved


def test_ctrl_click_pins_the_shape_and_cancel_removes_the_pin(addon):
    obj, left, right = rig_with_two_handles()
    before_points = checks.evaluated_mesh_points(obj).copy()
    before_objects = sorted(o.name for o in bpy.data.objects)
    modal, op, _ = operator_stand_in(addon, obj)
    middle = np.array(checks.world(obj, [0.0, 0.5, 0.0]))
    modal(op, bpy.context, event("LEFTMOUSE", "PRESS", middle, ctrl=True))
    pin = op.session.state.handle
    assert op.session.state.pinned and pin not in (left, right)
    assert len(obj.shapedeform.handles) == 3
    modal(op, bpy.context, event("MOUSEMOVE", "NOTHING", middle + np.array([0.0, 0.4, 0.0])))
    moved = checks.evaluated_mesh_points(obj)
    top_middle = np.argmin(np.linalg.norm(before_points - (middle - np.array(obj.location)), axis=1))
    assert moved[top_middle, 1] - before_points[top_middle, 1] > 0.2
    assert modal(op, bpy.context, event("RIGHTMOUSE", "PRESS")) == {"CANCELLED"}
    assert [i.object for i in obj.shapedeform.handles] == [left, right]
    assert sorted(o.name for o in bpy.data.objects) == before_objects
    assert checks.evaluated_mesh_points(obj).tobytes() == before_points.tobytes()

    # Confirming keeps the pin as a handle, so the pose holds.
    modal, op, _ = operator_stand_in(addon, obj)
    modal(op, bpy.context, event("LEFTMOUSE", "PRESS", middle, ctrl=True))
    modal(op, bpy.context, event("MOUSEMOVE", "NOTHING", middle + np.array([0.0, 0.4, 0.0])))
    assert modal(op, bpy.context, event("LEFTMOUSE", "RELEASE")) == {"FINISHED"}
    assert len(obj.shapedeform.handles) == 3


@pytest.mark.parametrize("ending", ["RET", "ESC"])
def test_a_pin_made_while_a_handle_is_active_takes_its_place_as_the_active_one(addon, ending):
    """With a handle the active object (as "+" leaves it), a Ctrl+click pin became the list's
    active item only until the view layer updated: the list follows the active object, so it
    went back to the handle, and "-" removed the handle instead of the pin (QA). The pin takes
    the handle's place as the active object; cancelling gives the handle back."""
    obj, left, right = rig_with_two_handles()
    view_layer = bpy.context.view_layer
    checks.select_only(right)
    modal, op, _ = operator_stand_in(addon, obj)
    middle = np.array(checks.world(obj, [0.0, 0.5, 0.0]))
    modal(op, bpy.context, event("LEFTMOUSE", "PRESS", middle, ctrl=True))
    pin = op.session.state.handle
    modal(op, bpy.context, event("MOUSEMOVE", "NOTHING", middle + np.array([0.0, 0.3, 0.0])))
    modal(op, bpy.context, event(ending, "PRESS"))
    view_layer.update()
    settings = obj.shapedeform
    if ending == "RET":
        assert view_layer.objects.active == pin and pin.select_get() and not right.select_get()
        assert settings.handles[settings.active_handle].object == pin
        assert bpy.ops.shapedeform.remove_handle(handle=pin.name) == {"FINISHED"}
        assert [item.object for item in settings.handles] == [left, right]
    else:
        assert view_layer.objects.active == right and right.select_get()
        assert settings.handles[settings.active_handle].object == right
        assert [item.object for item in settings.handles] == [left, right]


def test_a_handle_move_does_not_look_through_the_scenes_for_rigs_to_lock(addon, monkeypatch):
    """Blender updates a rig's collection of handles when a handle moves, and every move looked
    through every scene's objects (QA: 1.5 ms a drag step at 5,000 objects) for rigs shown in
    scenes that had not locked their interface. That collection shows no character."""
    handlers = addon.shapedeform_addon.handlers
    obj, left, right = rig_with_two_handles()
    looked = []
    lock = handlers._lock_scenes
    monkeypatch.setattr(handlers, "_lock_scenes", lambda **kw: looked.append(1) or lock(**kw))
    state = dragged_by_script(addon, obj, right, (0.0, 0.3, 0.0))
    addon.shapedeform_addon.drag.confirm(bpy.context, state)
    right.location.x += 0.1
    bpy.context.view_layer.update()
    assert looked == []
    props = bpy.data.collections.new("Props")
    bpy.context.scene.collection.children.link(props)
    bpy.context.view_layer.update()
    assert looked  # a collection that may hold a character


def test_cancelling_a_ctrl_click_gives_the_handle_list_back(addon):
    """A handle deleted for good stays listed (as deleted) until the user removes it, and the
    list's active item stays: cancelling a Ctrl+click dropped the deleted entry with its pin and
    moved the active item."""
    obj, left, right = rig_with_two_handles()
    gone = checks.add_handle(obj, checks.world(obj, [0.0, -0.5, 0.0]))
    bpy.data.objects.remove(gone)  # deleted for good: its entry names no Empty
    obj.shapedeform["active_handle"] = 0
    before = [item.object for item in obj.shapedeform.handles]
    modal, op, _ = operator_stand_in(addon, obj)
    middle = np.array(checks.world(obj, [0.0, 0.5, 0.0]))
    modal(op, bpy.context, event("LEFTMOUSE", "PRESS", middle, ctrl=True))
    assert op.session.state.pinned and obj.shapedeform.active_handle == 3
    assert modal(op, bpy.context, event("ESC", "PRESS")) == {"CANCELLED"}
    assert [item.object for item in obj.shapedeform.handles] == before == [left, right, None]
    assert obj.shapedeform.active_handle == 0
    # Removing a handle (the sidebar's "-") still clears the entries of those deleted for good.
    checks.select_only(obj)
    assert bpy.ops.shapedeform.remove_handle(handle=right.name) == {"FINISHED"}
    assert [item.object for item in obj.shapedeform.handles] == [left]


def test_a_drag_keeps_a_handles_locked_axes(addon):
    """A handle with Lock Location Y moves along X alone, as G moves it (QA: the drag moved it
    0.3 along the locked axis)."""
    obj, _, right = rig_with_two_handles()
    right.lock_location[1] = True
    start = np.array(right.location)
    dragged_by_script(addon, obj, right, (0.2, 0.3, 0.0))
    np.testing.assert_allclose(np.array(right.location) - start, [0.2, 0.0, 0.0], atol=1e-6)


@pytest.mark.parametrize("how", ["hidden", "disabled in viewports", "unselectable", "collection hidden"])
def test_a_drag_grabs_no_handle_the_user_cannot_select(addon, how):
    """As G, a click grabs only handles shown and selectable: the nearest one hidden, the drag
    takes the other; all hidden, it says how to get them back (QA: a hidden handle was grabbed)."""
    obj, left, right = rig_with_two_handles()
    drag = addon.shapedeform_addon.drag

    def hide(handle):
        if how == "hidden":
            handle.hide_set(True)
        elif how == "disabled in viewports":
            handle.hide_viewport = True
        elif how == "unselectable":
            handle.hide_select = True
        else:
            obj.shapedeform.handle_collection.hide_viewport = True

    hide(right)
    if how != "collection hidden":
        state = dragged_by_script(addon, obj, right, (0.0, 0.3, 0.0))
        assert state.handle == left
        drag.cancel(bpy.context, state)
        hide(left)
    with pytest.raises(addon.shapedeform_addon.sources.RigError, match="shows no handle that can be selected"):
        dragged_by_script(addon, obj, right, (0.0, 0.3, 0.0))


def test_clicks_that_grab_nothing_explain_why(addon):
    obj = grid()
    bpy.ops.shapedeform.bind()
    modal, op, reports = operator_stand_in(addon, obj)
    assert modal(op, bpy.context, event("LEFTMOUSE", "PRESS", (0.0, 0.0, 0.0))) == {"RUNNING_MODAL"}
    assert op.session.state is None and "no handles" in reports[-1]
    assert modal(op, bpy.context, event("WHEELUPMOUSE", "PRESS")) == {"PASS_THROUGH"}
    assert modal(op, bpy.context, event("RET", "PRESS")) == {"CANCELLED"}
    # Looking at the plane edge-on: the ray never meets it.
    drag = addon.shapedeform_addon.drag
    edge_on = (np.zeros(3), np.array([1.0, 0.0, 0.0]))
    try:
        drag.begin(bpy.context, obj, edge_on)
    except addon.shapedeform_addon.sources.RigError as err:
        assert "edge-on" in str(err)
    else:
        raise AssertionError("an edge-on ray grabbed something")


def test_a_baked_rig_offers_no_drag_and_says_why(addon):
    """Greyed out with the reason, as Blender's operators are (it was offered, then refused
    every click)."""
    obj, _, _ = rig_with_two_handles()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.drag.poll()
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=2) == {"FINISHED"}
    assert not bpy.ops.shapedeform.drag.poll()
    with pytest.raises(RuntimeError, match="plays its bake: clear the bake"):
        bpy.ops.shapedeform.drag("INVOKE_DEFAULT")
    assert bpy.ops.shapedeform.clear_bake() == {"FINISHED"}
    assert bpy.ops.shapedeform.drag.poll()


@pytest.fixture
def keying_preferences():
    """The keying preferences a test changes, put back afterwards (they outlive the file)."""
    edit = bpy.context.preferences.edit
    names = ("use_keyframe_insert_available", "use_auto_keyframe_insert_needed", "use_visual_keying")
    saved = {name: getattr(edit, name) for name in names}
    yield edit
    for name, value in saved.items():
        setattr(edit, name, value)


def test_auto_keying_keys_the_moved_handle(addon, keying_preferences):
    obj, left, right = rig_with_two_handles()
    scene = bpy.context.scene
    scene.tool_settings.use_keyframe_insert_auto = True
    keying_preferences.use_keyframe_insert_available = False  # on by default in Blender 5.2
    scene.frame_set(7)
    drag = addon.shapedeform_addon.drag
    state = dragged_by_script(addon, obj, right, (0.0, 0.3, 0.0))
    assert drag.confirm(bpy.context, state) == [right]
    animation = right.animation_data
    bag = anim_utils.action_get_channelbag_for_slot(animation.action, animation.action_slot)
    keyed = {(c.data_path, c.array_index): [tuple(k.co) for k in c.keyframe_points] for c in bag.fcurves}
    assert keyed[("location", 1)] == [(7.0, right.location.y)]
    assert left.animation_data is None
    # As Blender's auto-keying: the timeline's key type.
    scene.tool_settings.keyframe_type = "BREAKDOWN"
    scene.frame_set(9)
    state = dragged_by_script(addon, obj, right, (0.0, 0.2, 0.0))
    assert drag.confirm(bpy.context, state) == [right]
    curve = next(c for c in bag.fcurves if (c.data_path, c.array_index) == ("location", 1))
    assert [k.type for k in curve.keyframe_points] == ["KEYFRAME", "BREAKDOWN"]


def keyed(obj):
    """{(data path, index): [key frames]} of ``obj``'s action, {} when it has none."""
    animation = obj.animation_data
    if animation is None or animation.action is None:
        return {}
    bag = anim_utils.action_get_channelbag_for_slot(animation.action, animation.action_slot)
    return {(c.data_path, c.array_index): [round(k.co[0], 4) for k in c.keyframe_points] for c in bag.fcurves}


def in_viewport():
    """A context override in a 3D viewport (the first area of the window, turned into one)."""
    window = bpy.context.window
    area = window.screen.areas[0]
    area.type = "VIEW_3D"
    region = next(r for r in area.regions if r.type == "WINDOW")
    return bpy.context.temp_override(window=window, area=area, region=region)


def moved_with_g(obj, offset):
    """Blender's own move of ``obj`` alone, in a 3D viewport (what auto-keying answers to)."""
    checks.select_only(obj)
    with in_viewport():
        assert bpy.ops.transform.translate(value=offset) == {"FINISHED"}


def _animated_in_y(handle, frames):
    for frame in frames:
        handle.keyframe_insert("location", index=1, frame=frame)


def _keying_set(scene):
    scene.tool_settings.use_keyframe_insert_keyingset = True
    scene.keying_sets_all.active = next(k for k in scene.keying_sets_all if k.bl_idname == "BUILTIN_KSI_LocRot")


@pytest.mark.parametrize("setting", ["default", "only available", "only available, y animated", "keying set",
                                     "subframe", "replace mode, y animated", "replace mode, y keyed here",
                                     "replace mode, y keyed here, NLA tweak mode", "only needed, y animated"])
def test_auto_keying_keys_a_drag_as_blender_keys_a_move(addon, setting, keying_preferences):
    """A handle dragged with auto-keying on gets the keys Blender's G gives the other handle:
    the drag keyed location at the whole frame whatever the settings (keys on channels Only
    Insert Available leaves alone, none of the active keying set's rotation, a key at 4.0 that
    pulled a handle dropped at 4.5 back by 0.05; in an NLA strip's tweak mode Replace keyed
    nothing, comparing the scene's frame with the action's keys: QA)."""
    obj, left, right = rig_with_two_handles()
    scene = bpy.context.scene
    scene.tool_settings.use_keyframe_insert_auto = True
    keying_preferences.use_keyframe_insert_available = setting.startswith("only available")
    keying_preferences.use_auto_keyframe_insert_needed = setting.startswith("only needed")
    scene.tool_settings.auto_keying_mode = "REPLACE_KEYS" if setting.startswith("replace") else "ADD_REPLACE_KEYS"
    for handle in (left, right):
        _animated_in_y(handle, [1] if setting.endswith("animated") else [1, 4] if "keyed here" in setting else [])
        if setting.endswith("NLA tweak mode"):  # the action in a strip from frame 21: its frame 4 is 24
            animation = handle.animation_data
            strip = animation.nla_tracks.new().strips.new("Moves", 1, animation.action)
            animation.action = None
            strip.frame_start_ui, strip.select = 21, True
            animation.use_tweak_mode = True
    if setting == "keying set":
        _keying_set(scene)
    frame, subframe = (4, 0.5) if setting == "subframe" else (4, 0.0)
    frame += 20 if setting.endswith("NLA tweak mode") else 0
    scene.frame_set(frame, subframe=subframe)
    moved_with_g(left, (0.0, 0.2, 0.0))
    drag = addon.shapedeform_addon.drag
    state = dragged_by_script(addon, obj, right, (0.0, 0.2, 0.0))
    before = keyed(left)
    with in_viewport():  # where the drag runs (keying sets key through an operator)
        drag.confirm(bpy.context, state)
    assert keyed(right) == keyed(left) and (before != {} or setting.startswith("only available"))
    dropped = left.location.y, right.location.y
    scene.frame_set(frame + 2)
    scene.frame_set(frame, subframe=subframe)
    # Where the keys leave each: the dragged one as the moved one (dropped, or back on its curve).
    assert right.location.y - dropped[1] == pytest.approx(left.location.y - dropped[0], abs=1e-5)


def keyed_in_groups(obj):
    """{(data path, index, F-Curve group): [key frames]} of ``obj``'s action."""
    animation = obj.animation_data
    bag = anim_utils.action_get_channelbag_for_slot(animation.action, animation.action_slot)
    return {(c.data_path, c.array_index, c.group.name if c.group else ""):
            [round(k.co[0], 4) for k in c.keyframe_points] for c in bag.fcurves}


def no_viewport_anywhere():
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.type = "PROPERTIES"


@pytest.mark.parametrize("keying_set", ["the user's", "built-in"])
@pytest.mark.parametrize("where", ["a script", "no 3D viewport anywhere"])
def test_auto_keying_through_the_active_keying_set_outside_a_viewport(addon, keying_set, where):
    """The drag's functions are for scripts too: with Only Active Keying Set on, confirm()
    raised (Blender's keying operator wants an area). Keyed as Blender keys through the set: a
    set of the user's keys its paths (not another set's), a built-in one what it keys on the
    handle, both in the groups Blender's operator makes."""
    obj, left, right = rig_with_two_handles()
    other = bpy.data.objects.new("Other", None)
    bpy.context.scene.collection.objects.link(other)
    scene = bpy.context.scene
    scene.tool_settings.use_keyframe_insert_auto = True
    scene.frame_set(4)
    if keying_set == "the user's":
        scene.keying_sets.new(name="Others").paths.add(other, "location")
        own = scene.keying_sets.new(name="Dragged")
        own.paths.add(right, "location")
        own.paths.add(left, "location", index=1, group_method="NAMED", group_name="Left Y")
        scene.tool_settings.use_keyframe_insert_keyingset = True
        scene.keying_sets.active = own
        expected = {("location", i, "Dragged"): [4.0] for i in range(3)}
    else:
        _keying_set(scene)
        checks.select_only(left)  # Blender's own keying of the other handle through the set
        with in_viewport():
            assert bpy.ops.anim.keyframe_insert_by_name(type=scene.keying_sets_all.active.bl_idname) == {"FINISHED"}
        expected = keyed_in_groups(left)
    if where == "no 3D viewport anywhere":
        no_viewport_anywhere()
    drag = addon.shapedeform_addon.drag
    state = dragged_by_script(addon, obj, right, (0.0, 0.2, 0.0))
    assert drag.confirm(bpy.context, state) == [right]
    assert keyed_in_groups(right) == expected
    assert other.animation_data is None
    if keying_set == "the user's":  # the set's path on the other handle too, in its own group
        assert keyed_in_groups(left) == {("location", 1, "Left Y"): [4.0]}


def test_undo_after_a_drag_gives_back_the_pose_and_the_rig_keeps_working(addon):
    obj, left, right = rig_with_two_handles()
    before = checks.evaluated_mesh_points(obj).copy()
    bpy.ops.ed.undo_push(message="before drag")
    drag = addon.shapedeform_addon.drag
    start = np.array(right.matrix_world.translation)
    state = dragged_by_script(addon, obj, right, (0.0, 0.4, 0.0))
    drag.confirm(bpy.context, state)
    bpy.ops.ed.undo_push(message="Drag Handle")
    dragged = checks.evaluated_mesh_points(obj).copy()
    assert np.abs(dragged - before).max() > 0.2

    bpy.ops.ed.undo()
    obj = bpy.data.objects["Grid"]
    right = obj.shapedeform.handles[1].object
    np.testing.assert_allclose(right.matrix_world.translation, start, atol=1e-6)
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), before, atol=1e-6)
    bpy.ops.ed.redo()
    obj = bpy.data.objects["Grid"]
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), dragged, atol=1e-6)
    # The rig was rebuilt lazily after undo and redo: moving a handle still poses.
    obj.shapedeform.handles[1].object.location.y -= 0.4
    bpy.context.view_layer.update()
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), before, atol=1e-4)
    assert obj.shapedeform.status == ""


@pytest.mark.parametrize("constraint", ["CHILD_OF", "ARMATURE"])
def test_a_handle_under_a_turned_child_of_moves_with_the_mouse(addon, constraint):
    """A handle the animator constrained (Child Of a controller, or an Armature constraint to a
    bone, as riggers attach props, then turned a quarter turn) moves where the mouse moves (its
    location was read in its rig's space alone: it moved the mouse's offset turned 90 degrees,
    QA: 0.41 from the mouse with a bone turned 1.2)."""
    obj, left, right = rig_with_two_handles()
    if constraint == "CHILD_OF":
        controller = bpy.data.objects.new("Controller", None)
        bpy.context.scene.collection.objects.link(controller)
        follow = right.constraints.new("CHILD_OF")
        follow.target = controller
        follow.inverse_matrix = controller.matrix_world.inverted()
        controller.rotation_euler.z = np.pi / 2
    else:
        armature = bpy.data.objects.new("Armature", bpy.data.armatures.new("Armature"))
        bpy.context.scene.collection.objects.link(armature)
        checks.select_only(armature)
        bpy.ops.object.mode_set(mode="EDIT")
        bone = armature.data.edit_bones.new("Bone")
        bone.head, bone.tail = (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)
        bpy.ops.object.mode_set(mode="OBJECT")
        follow = right.constraints.new("ARMATURE")
        target = follow.targets.new()
        target.target, target.subtarget = armature, "Bone"
        armature.pose.bones["Bone"].rotation_mode = "XYZ"
        armature.pose.bones["Bone"].rotation_euler.y = np.pi / 2  # about the bone's own axis: world z
    bpy.context.view_layer.update()
    modal, op, _ = operator_stand_in(addon, obj)
    start = np.array(right.matrix_world.translation)
    assert modal(op, bpy.context, event("LEFTMOUSE", "PRESS", start)) == {"RUNNING_MODAL"}
    assert op.session.state.handle == right
    modal(op, bpy.context, event("MOUSEMOVE", "NOTHING", start + np.array([0.3, 0.2, 0.0])))
    np.testing.assert_allclose(np.array(right.matrix_world.translation) - start, [0.3, 0.2, 0.0], atol=1e-5)


def test_ctrl_click_where_the_pose_overlaps_itself_pins_the_part_in_front(addon):
    """An arm swung across the torso is drawn in front of it: Ctrl+click on it pins the arm.
    The point nearest the click on the plane was often the torso's, left on the plane under
    the arm (8 of 13 clicks on a grease-pencil arm), so the drag pulled the hidden torso."""
    from test_overlap_depth import forearm_over_torso, swung_figure

    rig_format = addon.shapedeform_addon.rig_format
    obj, _, rest, posed = swung_figure()
    over_torso = forearm_over_torso(rest, posed)
    assert len(over_torso) >= 4
    for k in over_torso:
        modal, op, _ = operator_stand_in(addon, obj)
        click = np.array(checks.world(obj, posed[k]))
        click[2] = 0.0  # on the plane, where the ray from the view meets it
        modal(op, bpy.context, event("LEFTMOUSE", "PRESS", click, ctrl=True))
        region = np.asarray(obj.shapedeform.handles[-1][rig_format.HANDLE_INDICES])
        assert np.all(rest[region, 0] > 0.3 + 1e-6), f"a click on the arm at {posed[k]} pinned the torso"
        assert modal(op, bpy.context, event("RIGHTMOUSE", "PRESS")) == {"CANCELLED"}
