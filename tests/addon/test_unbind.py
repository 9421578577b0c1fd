# SPDX-License-Identifier: GPL-3.0-or-later
"""Unbinding gives the object back whatever state its rig is in: baked (issue 15, defect 8),
duplicated (defect 9), or broken by a deleted grease-pencil keyframe (defect 10)."""

import bpy
import numpy as np
import pytest

import rig_checks as checks
from test_bake import rig
from test_rig_curve import curve_points, text_curve
from test_rig_grease_pencil import drawing_points
from test_rig_mesh import grid, rig_with_two_handles


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
    evaluated = lambda: np.concatenate(curve_points(obj.evaluated_get(bpy.context.evaluated_depsgraph_get())))
    return obj, rest[np.argmin(rest[:, 1])], rest[np.argmax(rest[:, 1])], evaluated


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
    assert np.abs(evaluated() - rest).max() > 0.1  # the bake plays

    unbind(obj)
    assert "baked" not in obj.shapedeform and "baked_gp_frames" not in obj.shapedeform
    for frame in (1, 4, 6):  # the object is back to its own shape on every frame
        scene.frame_set(frame)
        assert evaluated().tobytes() == rest.tobytes(), f"frame {frame}"
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
    assert np.abs(evaluated() - rest).max() > 0.1


def test_unbinding_a_duplicate_leaves_the_original_rig_alone(addon):
    original, left, right = rig_with_two_handles()
    collection = original.shapedeform.handle_collection
    names = {original.name, left.name, right.name}
    for o in bpy.context.selected_objects:
        o.select_set(False)
    original.select_set(True)
    bpy.context.view_layer.objects.active = original
    assert bpy.ops.object.duplicate() == {"FINISHED"}  # Shift+D: the handles are not duplicated
    copy = bpy.context.active_object
    assert copy is not original and copy.shapedeform.is_bound
    saved = copy.data.attributes["sd_rest"]  # the copy's mesh is a copy: its rest came along
    rest = np.empty(len(saved.data) * 3, np.float32)
    saved.data.foreach_get("vector", rest)
    rest = rest.reshape(-1, 3)

    unbind(copy)
    assert not copy.shapedeform.is_bound and len(copy.shapedeform.handles) == 0
    assert checks.mesh_points(copy).tobytes() == rest.tobytes()
    # The original keeps its handles, their collection, and a working rig.
    assert {o.name for o in bpy.data.objects} == names | {copy.name}
    assert [item.object for item in original.shapedeform.handles] == [left, right]
    assert collection.name in bpy.data.collections and set(collection.objects) == {left, right}
    _assert_still_follows(original, right, rest)

    # Unbinding the original afterwards still removes its own handles and collection.
    unbind(original)
    assert {o.name for o in bpy.data.objects} == {original.name, copy.name}
    assert not any("Handles" in c.name for c in bpy.data.collections)


def _assert_still_follows(original, handle, rest):
    """The original's rig is live: moving its right handle up moves the grid's right tip."""
    handle.location.y += 0.4
    bpy.context.view_layer.update()
    assert original.shapedeform.status == ""
    tip = np.argmin(np.linalg.norm(rest[:, :2] - [1.0, 0.0], axis=1))
    assert checks.evaluated_mesh_points(original)[tip, 1] == pytest.approx(0.4, abs=1e-5)


def test_a_grease_pencil_rig_that_lost_its_drawing_can_be_unbound(addon, capfd):
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    obj.name = "Monkey"
    lines = obj.data.layers["Lines"]
    rest = drawing_points(obj, evaluated=False)
    fills_count = len(obj.data.layers["Fills"].current_frame().drawing.attributes["position"].data)
    lines_rest = rest[fills_count:].copy()  # drawing_points reads Fills, then Lines
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, rest[np.argmin(rest[:, 2])]))
    handle = checks.add_handle(obj, checks.world(obj, rest[np.argmax(rest[:, 2])]))
    handle.location.x += 0.3
    bpy.context.view_layer.update()
    assert np.abs(drawing_points(obj) - rest).max() > 0.1

    obj.data.layers["Fills"].frames.remove(1)  # the animator deletes the rigged keyframe
    handle.location.x += 0.1
    bpy.context.view_layer.update()
    assert "lost the drawing of layer 'Fills'" in obj.shapedeform.status
    capfd.readouterr()

    unbind(obj)
    printed = capfd.readouterr().out
    assert "Warning" in printed and "'Fills'" in printed  # what could not be restored, said once
    assert not obj.shapedeform.is_bound
    assert not any(key in obj.shapedeform for key in ("gp_layers", "gp_frames", "graph_points", "plane"))
    assert [o.name for o in bpy.data.objects] == ["Monkey"]
    assert not any("Handles" in c.name for c in bpy.data.collections)
    drawing = lines.current_frame().drawing
    assert "sd_rest" not in drawing.attributes
    flat = np.empty(len(drawing.attributes["position"].data) * 3, np.float32)
    drawing.attributes["position"].data.foreach_get("vector", flat)
    assert flat.tobytes() == lines_rest.tobytes()  # what was left is given back exactly


def test_unbinding_a_linked_duplicate_leaves_the_shared_data_to_the_original(addon):
    """Alt+D shares the mesh: giving back its rest shape would take the original's rig data."""
    original, left, right = rig_with_two_handles()
    saved = original.data.attributes["sd_rest"]
    rest = np.empty(len(saved.data) * 3, np.float32)
    saved.data.foreach_get("vector", rest)
    rest = rest.reshape(-1, 3)
    for o in bpy.context.selected_objects:
        o.select_set(False)
    original.select_set(True)
    bpy.context.view_layer.objects.active = original
    assert bpy.ops.object.duplicate(linked=True) == {"FINISHED"}
    copy = bpy.context.active_object
    assert copy.data == original.data

    unbind(copy)
    assert not copy.shapedeform.is_bound and "graph_points" not in copy.shapedeform
    assert "sd_rest" in original.data.attributes
    _assert_still_follows(original, right, rest)
    unbind(original)
    assert checks.mesh_points(original).tobytes() == rest.tobytes()
