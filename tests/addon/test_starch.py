# SPDX-License-Identifier: GPL-3.0-or-later
"""Starch pins (issue 14): the shape near a starch pin bends less; its amount is keyable."""

import bpy
import numpy as np
import pytest
from mathutils import Matrix

import rig_checks as checks


def bar():
    """A bar 8 long and 1 wide, bound, with a handle holding each end."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=48, y_subdivisions=6, size=1.0)
    obj = bpy.context.active_object
    obj.data.transform(Matrix.Diagonal((8.0, 1.0, 1.0, 1.0)))
    bpy.context.view_layer.update()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, (-3.8, 0.0, 0.0))
    end = checks.add_handle(obj, (3.8, 0.0, 0.0))
    return obj, end


def curl(end):
    """Turn the right end a quarter turn and bring it over the middle: the bar curls."""
    end.rotation_euler.z = np.pi / 2
    end.location = (1.5, 2.5, 0.0)
    bpy.context.view_layer.update()


def turning(rest, posed, region):
    """How far the bar's direction turns across ``region`` (a mask): the angle between the
    best-fit directions of its first and last thirds along the bar."""
    xs = rest[region, 0]
    lo, hi = np.quantile(xs, [1 / 3, 2 / 3])
    ahead = posed[region][xs > hi, :2].mean(axis=0) - posed[region][xs < lo, :2].mean(axis=0)

    def direction(mask):
        points = posed[region][mask, :2]
        axis = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)[2][0]
        return axis * np.sign(axis @ ahead)

    return float(np.arccos(np.clip(direction(xs < lo) @ direction(xs > hi), -1.0, 1.0)))


def test_a_starch_pin_halves_the_bend_inside_its_extent_and_its_amount_keys(addon):
    obj, end = bar()
    rest = checks.mesh_points(obj).copy()
    middle = np.abs(rest[:, 0]) < 1.2
    curl(end)
    plain = turning(rest, checks.evaluated_mesh_points(obj), middle)
    assert plain > 0.15, "the bar does not bend through its middle"

    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.add_handle(location=(0.0, 0.0, 0.0), kind="STARCH") == {"FINISHED"}
    pin = obj.shapedeform.handles[-1].object
    assert pin.shapedeform.pin_kind == "STARCH" and pin.shapedeform.stiffness == 10.0
    pin.shapedeform.extent = 0.25  # 2 of the bar's 8.06 through the shape, full strength to 1.4
    pin.shapedeform.stiffness = 30.0
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    starched = turning(rest, checks.evaluated_mesh_points(obj), middle)
    assert starched < 0.5 * plain, f"bend across the starched middle {starched:.3f}, plain {plain:.3f}"

    # Keyed: no stiffness at frame 1, starched at frame 2; frames agree in any order.
    pin.shapedeform.stiffness = 0.0
    pin.keyframe_insert("shapedeform.stiffness", frame=1)
    pin.shapedeform.stiffness = 30.0
    pin.keyframe_insert("shapedeform.stiffness", frame=2)
    scene = bpy.context.scene
    scene.frame_set(2)
    at_two = checks.evaluated_mesh_points(obj).copy()
    scene.frame_set(1)
    assert turning(rest, checks.evaluated_mesh_points(obj), middle) == pytest.approx(plain, rel=1e-3)
    scene.frame_set(2)
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), at_two, atol=1e-6)
    assert turning(rest, at_two, middle) < 0.5 * plain


def test_render_animation_renders_each_frames_keyed_stiffness(addon, tmp_path):
    """Render Animation, as a farm runs it, poses frame 2 with frame 2's keyed stiffness, as a
    still render of that frame does (the render's depsgraph keeps the frame's value in its
    evaluated copies only: the bar rendered as stiff as at the frame the render started from)."""
    import renders

    obj, end = bar()
    curl(end)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.add_handle(location=(0.0, 0.0, 0.0), kind="STARCH") == {"FINISHED"}
    pin = obj.shapedeform.handles[-1].object
    pin.shapedeform.extent = 0.25
    pin.shapedeform.stiffness = 0.0
    pin.keyframe_insert("shapedeform.stiffness", frame=1)
    pin.shapedeform.stiffness = 30.0
    pin.keyframe_insert("shapedeform.stiffness", frame=2)
    renders.camera_over((0.0, 1.0), 9.0)
    scene = bpy.context.scene
    still = {}
    for frame in (1, 2):
        scene.frame_set(frame)
        still[frame] = renders.render(tmp_path / f"still{frame}.png", size=96)
    assert np.mean(np.abs(still[1] - still[2]).max(axis=2) > 0.1) > 0.005  # the stiffness shows
    animated = renders.animation_frame(2, tmp_path, "farm", size=96)
    assert np.mean(np.abs(animated - still[2]).max(axis=2) > 0.1) < 1e-3


def keyed_pins(obj, end):
    """An overlap pin on the curled bar's end keyed from -1 to 1 and a starch pin in its middle
    keyed from 0 to 80, frames 1 to 5; returns each frame's pose {1: (n, 3), 5: (n, 3)}."""
    curl(end)
    keys = {}
    for location, kind, name, values in (((3.5, 0.0, 0.0), "OVERLAP", "in_front", (-1.0, 1.0)),
                                         ((0.0, 0.0, 0.0), "STARCH", "stiffness", (0.0, 80.0))):
        bpy.context.view_layer.objects.active = obj
        assert bpy.ops.shapedeform.add_handle(location=location, kind=kind) == {"FINISHED"}
        pin = obj.shapedeform.handles[-1].object
        for frame, value in zip((1, 5), values):
            setattr(pin.shapedeform, name, value)
            pin.keyframe_insert(f"shapedeform.{name}", frame=frame)
    scene = bpy.context.scene
    for frame in (1, 5):
        scene.frame_set(frame)
        keys[frame] = checks.evaluated_mesh_points(obj).copy()
    assert np.abs(keys[5] - keys[1]).max() > 0.1  # the amounts show
    return keys


@pytest.mark.parametrize("hidden", ["collection disabled in viewports", "collection hidden", "pins disabled"])
def test_keyed_pin_amounts_play_and_bake_with_the_handles_hidden(addon, hidden):
    """Hiding or disabling the rig's handles changes no frame's pose, live or baked (with the
    collection disabled in viewports the pins' keyed amounts stayed where they last were: 0.63
    off on this bar 8 long); Unbind takes away what keeps them evaluated."""
    obj, end = bar()
    keys = keyed_pins(obj, end)
    collection = obj.shapedeform.handle_collection
    if hidden == "collection disabled in viewports":
        collection.hide_viewport = True
    elif hidden == "collection hidden":
        bpy.context.view_layer.layer_collection.children[collection.name].hide_viewport = True
    else:
        for item in obj.shapedeform.handles[2:]:
            item.object.hide_viewport = True
    scene = bpy.context.scene
    for frame in (5, 1, 5):
        scene.frame_set(frame)
        np.testing.assert_allclose(checks.evaluated_mesh_points(obj), keys[frame], atol=1e-5, err_msg=str(frame))
    checks.select_only(obj)
    assert bpy.ops.shapedeform.bake(frame_start=1, frame_end=5) == {"FINISHED"}
    for frame in (1, 5):
        scene.frame_set(frame)
        np.testing.assert_allclose(checks.evaluated_mesh_points(obj), keys[frame], atol=1e-5, err_msg=f"baked {frame}")
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert obj.animation_data is None


def test_keyed_pin_amounts_render_with_the_handles_disabled_in_renders(addon, tmp_path):
    """Render Animation with the handle collection disabled in renders renders each frame's
    keyed amounts (it rendered frame 5 with frame 1's: 6.4% of the pixels)."""
    import renders

    obj, end = bar()
    keyed_pins(obj, end)
    renders.camera_over((0.0, 1.0), 9.0)
    scene = bpy.context.scene
    scene.frame_set(5)
    shown = renders.render(tmp_path / "shown.png", size=96)
    scene.frame_set(1)
    obj.shapedeform.handle_collection.hide_render = True
    animated = renders.animation_frame(5, tmp_path, "hidden", size=96)
    assert np.mean(np.abs(animated - shown).max(axis=2) > 0.1) < 1e-3


def test_starch_pins_show_in_the_sidebar_and_overlay(addon):
    from test_ui_overlay import drawn

    obj, _ = bar()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.add_handle(location=(0.0, 0.0, 0.0), kind="STARCH") == {"FINISHED"}
    bpy.context.view_layer.objects.active = obj
    items = drawn(bpy.context)
    assert "stiffness" in items and "extent" in items and "in_front" not in items
    obj.shapedeform.show_overlay = True
    data = addon.shapedeform_addon.overlay.drawing_data(obj)
    blue = data["reach_colors"][:, 2] > data["reach_colors"][:, 0]
    assert blue.sum() > 10 and np.all(np.abs(data["reach"][blue, 0]) < 0.25 * 8.07)


@pytest.mark.parametrize("kind", ["OVERLAP", "STARCH"])
def test_pins_added_at_a_selection_copied_or_off_the_shape(addon, capsys, kind):
    """Edit Mode with a hand's points selected adds one pin for them (it added a pin per point,
    and 63 overlap pins at 1 lifted the hand 1.26 of the shape's size); a pin's shape follows its
    extent; a pin added off the shape says where it went; Remove on a copy of a pin (Shift+D,
    which the rig does not list) says so rather than report that it removed it."""
    obj, _ = bar()
    points = checks.mesh_points(obj)
    selected = points[:, 0] > 2.5
    obj.data.vertices.foreach_set("select", selected)
    for elements in (obj.data.edges, obj.data.polygons):  # Edit Mode would flush their selection
        elements.foreach_set("select", np.zeros(len(elements), bool))
    before = len(obj.shapedeform.handles)
    checks.select_only(obj)
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.shapedeform.add_handle(kind=kind) == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    assert len(obj.shapedeform.handles) == before + 1
    pin = obj.shapedeform.handles[-1].object
    bpy.context.view_layer.update()
    assert abs(pin.matrix_world.translation.x - points[selected, 0].mean()) < 0.2
    size = pin.empty_display_size / pin.shapedeform.extent
    pin.shapedeform.extent = 0.5
    assert abs(pin.empty_display_size - 0.5 * size) < 1e-6 * size

    checks.select_only(obj)
    capsys.readouterr()
    assert bpy.ops.shapedeform.add_handle(location=(10.0, 10.0, 0.0), kind=kind) == {"FINISHED"}
    assert "pin was added off the shape: it is on the shape's nearest point" in capsys.readouterr().out

    checks.select_only(pin)
    assert bpy.ops.object.duplicate() == {"FINISHED"}
    copy = bpy.context.active_object
    assert copy != pin and copy.shapedeform.rig == obj
    count = len(obj.shapedeform.handles)
    with pytest.raises(RuntimeError, match="not in the handle list of its rig \\(a copy of a handle\\?\\)"):
        bpy.ops.shapedeform.remove_handle()
    assert len(obj.shapedeform.handles) == count


@pytest.mark.parametrize("kind", ["OVERLAP", "STARCH"])
def test_a_pins_shape_shows_its_extent_in_the_world_on_a_scaled_object(addon, kind):
    """A pin's sphere or cube is as big as its extent on the shape as the viewport shows it: on
    an object scaled 2 it was half that (a pin rides on a cage point and takes none of its
    scale), and it follows a change of the object's scale."""
    obj, _ = bar()
    obj.scale = (2.0, 2.0, 2.0)
    bpy.context.view_layer.update()
    checks.select_only(obj)
    assert bpy.ops.shapedeform.add_handle(location=(0.0, 0.0, 0.0), kind=kind) == {"FINISHED"}
    pin = obj.shapedeform.handles[-1].object
    bpy.context.view_layer.update()

    def shown_over_reach():
        world = checks.mesh_points(obj) * np.array(obj.scale)
        size = np.linalg.norm(np.ptp(world, axis=0)[:2])  # the shape's size, as the graph measures it
        return pin.empty_display_size * max(pin.matrix_world.to_scale()) / (pin.shapedeform.extent * size)

    assert shown_over_reach() == pytest.approx(1.0, rel=0.02)
    pin.shapedeform.extent = 0.5
    assert shown_over_reach() == pytest.approx(1.0, rel=0.02)
    obj.scale = (3.0, 3.0, 3.0)
    bpy.context.view_layer.update()
    assert shown_over_reach() == pytest.approx(1.0, rel=0.02)
