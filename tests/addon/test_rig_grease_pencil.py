# SPDX-License-Identifier: GPL-3.0-or-later
"""Rigging Blender's own grease-pencil monkey (GPv3, drawn in the XZ plane)."""

import bpy
import numpy as np
import pytest

import rig_checks as checks


def drawing_points(obj, evaluated=True):
    if evaluated:
        return checks.evaluated_drawing_points(obj)
    return np.concatenate([checks.drawing_points(layer.current_frame().drawing) for layer in obj.data.layers])


def test_monkey_follows_its_handles_and_unbinds_exactly(addon, tmp_path):
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    obj.name = "Monkey"
    rest = drawing_points(obj, evaluated=False).copy()
    assert np.ptp(rest[:, 1]) == 0  # Blender draws it in XZ
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    top = rest[np.argmax(rest[:, 2])]
    bottom = rest[np.argmin(rest[:, 2])]
    checks.add_handle(obj, checks.world(obj, bottom))
    handle = checks.add_handle(obj, checks.world(obj, top))
    np.testing.assert_allclose(drawing_points(obj), rest, atol=1e-5)  # adding moves nothing
    handle.location.x += 0.3
    bpy.context.view_layer.update()
    posed = drawing_points(obj)
    assert np.all(np.isfinite(posed))
    checks.assert_in_front_only(rest, posed, (0, -1.0, 0), 2.0)  # in the XZ plane, or lifted toward -Y
    tip = np.argmin(np.linalg.norm(rest - top, axis=1))
    assert posed[tip, 0] == pytest.approx(top[0] + 0.3, abs=0.02)
    assert posed[tip, 2] == pytest.approx(top[2], abs=0.02)
    assert np.abs(posed - rest).max() == pytest.approx(0.3, abs=0.05)

    path = str(tmp_path / "monkey.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Monkey"]
    assert drawing_points(obj, evaluated=False).tobytes() == rest.tobytes()  # the pose is the modifier's
    np.testing.assert_array_equal(drawing_points(obj), posed)
    obj.shapedeform.handles[1].object.location.x -= 0.3
    bpy.context.view_layer.update()
    np.testing.assert_allclose(drawing_points(obj), rest, atol=1e-4)

    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert drawing_points(obj, evaluated=False).tobytes() == rest.tobytes()
    assert [o.name for o in bpy.data.objects] == ["Monkey"]
    for layer in obj.data.layers:
        assert "sd_rest" not in layer.current_frame().drawing.attributes


def test_chosen_layers_only(addon):
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    obj.shapedeform.layers = "Lines"
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    rest = {name: checks.drawing_points(obj.data.layers[name].current_frame().drawing).copy()
            for name in ("Fills", "Lines")}
    lines = rest["Lines"]
    checks.add_handle(obj, checks.world(obj, lines[np.argmin(lines[:, 2])]))
    handle = checks.add_handle(obj, checks.world(obj, lines[np.argmax(lines[:, 2])]))
    handle.location.x += 0.3
    bpy.context.view_layer.update()
    assert np.abs(checks.evaluated_drawing_points(obj, "Lines") - rest["Lines"]).max() > 0.2
    assert checks.evaluated_drawing_points(obj, "Fills").tobytes() == rest["Fills"].tobytes()
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert "sd_rigged" not in obj.data.attributes
    bpy.context.view_layer.objects.active = obj
    obj.shapedeform.layers = "Nope"
    with pytest.raises(RuntimeError, match="no layer 'Nope'"):
        bpy.ops.shapedeform.bind()


@pytest.mark.parametrize("then", ["add", "delete"])
def test_a_chosen_layer_renamed_as_a_layer_comes_or_goes_stays_rigged(addon, quiet, then):
    """A chosen layer renamed while another is added or deleted, with no update between (one
    script, or the extension off): the marks were set again from the chosen layers' names, none
    of which was left, and the layer stopped deforming for good (QA: 0.5 of pose to 0)."""
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    obj.shapedeform.layers = "Lines"
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    lines = checks.drawing_points(obj.data.layers["Lines"].current_frame().drawing).copy()
    checks.add_handle(obj, checks.world(obj, lines[np.argmin(lines[:, 2])]))
    handle = checks.add_handle(obj, checks.world(obj, lines[np.argmax(lines[:, 2])]))
    handle.location.x += 0.3
    bpy.context.view_layer.update()
    posed = checks.evaluated_drawing_points(obj, "Lines").copy()
    assert np.abs(posed - lines).max() > 0.2
    obj.data.layers["Lines"].name = "Outline"
    if then == "add":
        obj.data.layers.new("Sketch")
    else:
        obj.data.layers.remove(obj.data.layers["Fills"])
    bpy.context.view_layer.update()
    np.testing.assert_allclose(checks.evaluated_drawing_points(obj, "Outline"), posed, atol=1e-6)
    if then == "add":
        assert checks.evaluated_drawing_points(obj, "Fills").tobytes() == \
            checks.drawing_points(obj.data.layers["Fills"].current_frame().drawing).tobytes()


def test_strokes_inside_a_fill_move_with_it(addon):
    """The monkey's skin is drawn with a fill material on strokes that are not closed: Blender
    fills them, so the shape is the filled face, and its mouth and eyes move with it (only the
    outlines made the shape: every inner stroke was an island of its own and stayed at rest).
    Up to 5.0 the material's Fill switch says so; 5.1 marks each filled stroke (``fill_id``)."""
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    rest = drawing_points(obj, evaluated=False).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    centre = (rest.min(axis=0) + rest.max(axis=0)) / 2
    chin = rest[np.argmin(rest[:, 2])]
    checks.add_handle(obj, checks.world(obj, centre))
    handle = checks.add_handle(obj, checks.world(obj, chin))
    handle.location.z -= 0.3
    bpy.context.view_layer.update()
    moved = np.linalg.norm(drawing_points(obj) - rest, axis=1)
    offsets = np.concatenate([[0], np.cumsum([len(layer.current_frame().drawing.strokes)
                                             for layer in obj.data.layers])])
    sizes = np.concatenate([[len(s.points) for s in layer.current_frame().drawing.strokes]
                            for layer in obj.data.layers])
    stroke_of = np.repeat(np.arange(len(sizes)), sizes)
    still = [s for s in range(len(sizes)) if moved[stroke_of == s].max() < 1e-4]
    assert still == []


def test_a_drawing_with_an_empty_layer_binds(addon):
    """Add > Grease Pencil > Stroke keys an empty drawing on its fill layer: Bind rigs the
    strokes there are (it raised numpy's length mismatch from the empty drawing)."""
    bpy.ops.object.grease_pencil_add(type="STROKE")
    obj = bpy.context.active_object
    assert any(len(layer.current_frame().drawing.strokes) == 0 for layer in obj.data.layers)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert obj.shapedeform.is_bound


@pytest.mark.parametrize("count", [2, 20])
def test_a_straight_stroke_is_rigged_in_the_drawing_plane(addon, count):
    """A straight stroke (a stick, a tail) lies in many planes: it is rigged in the XZ plane
    Blender draws in, as a bent one is (it was refused: "all its points lie on one line")."""
    bpy.ops.object.grease_pencil_add(type="EMPTY")
    obj = bpy.context.active_object
    layer = obj.data.layers[0] if len(obj.data.layers) else obj.data.layers.new("Lines")
    drawing = (layer.current_frame() or layer.frames.new(bpy.context.scene.frame_current)).drawing
    drawing.add_strokes([count])
    line = np.stack([np.linspace(0.0, 2.0, count), np.zeros(count), np.zeros(count)], axis=1)
    drawing.attributes["position"].data.foreach_set("vector", line.astype(np.float32).ravel())
    radius = drawing.attributes.get("radius") or drawing.attributes.new("radius", "FLOAT", "POINT")
    radius.data.foreach_set("value", np.full(count, 0.02, np.float32))
    bpy.context.view_layer.update()
    _, end = checks.bind_with_handles(obj, line[0], line[-1])
    end.location.z += 0.5
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    moved = drawing_points(obj)
    assert moved[-1][[0, 2]] == pytest.approx([2.0, 0.5], abs=0.02)
    assert np.abs(moved[:, 1]).max() < 0.05  # in the XZ plane (or barely lifted)


@pytest.mark.parametrize("how", ["transform", "parent moved", "parent in place"])
def test_bind_warns_about_a_layer_moved_by_its_own_transform_or_parent(addon, capsys, how):
    """A parent moved since the layer was parented moves its strokes as a layer transform does
    (handles put on them were a quarter of the shape's size off it), and Bind said nothing."""
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    monkey = bpy.context.active_object
    layer = monkey.data.layers["Lines"]
    if how == "transform":
        layer.translation = (2.0, 0.0, 0.0)
    else:
        empty = bpy.data.objects.new("Parent", None)
        bpy.context.scene.collection.objects.link(empty)
        empty.location = (2.0, 0.0, 0.0)
        bpy.context.view_layer.update()
        layer.parent = empty  # which keeps the strokes in place (the parent's inverse)
        if how == "parent moved":
            empty.location.x += 1.0
        bpy.context.view_layer.update()
    bpy.context.view_layer.objects.active = monkey
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    warned = "'Lines' is moved by a layer transform or parent" in capsys.readouterr().out
    assert warned == (how != "parent in place")


def test_a_layer_named_with_a_comma_can_be_chosen_and_hidden_layers_rigged_are_named(addon, capsys):
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    obj.data.layers["Lines"].name = "Lines, ink"
    obj.shapedeform.layers = "Lines, ink"  # one layer, not two ('Lines' and 'ink' do not exist)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    marks = obj.data.attributes[obj.shapedeform[addon.shapedeform_addon.rig_format.RIGGED_KEY]]
    values = np.zeros(len(obj.data.layers), dtype=bool)
    marks.data.foreach_get("value", values)
    assert [layer.name for layer, rigged in zip(obj.data.layers, values) if rigged] == ["Lines, ink"]
    capsys.readouterr()

    bpy.ops.object.grease_pencil_add(type="MONKEY")
    hidden = bpy.context.active_object
    hidden.data.layers["Fills"].hide = True  # a reference drawing, say: it still shapes the rig
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert "the hidden layer 'Fills' is part of the shape" in capsys.readouterr().out


def test_a_drawing_far_from_its_origin_stays_put_at_bind(addon):
    """A stroke 2.6 wide drawn 1e6 from its object's origin (float32 steps there: 0.0625):
    Bind and a handle, nothing moved, threw points 62,680 away (each triangle's map applied in
    absolute coordinates, its rounding times 1e6). Maps applied about their triangle's corner
    keep it within a few steps of the data's own precision."""
    import math

    bpy.ops.object.grease_pencil_add(type="EMPTY")
    obj = bpy.context.active_object
    layer = obj.data.layers[0] if len(obj.data.layers) else obj.data.layers.new("Lines")
    drawing = (layer.current_frame() or layer.frames.new(bpy.context.scene.frame_current)).drawing
    t = np.linspace(0, 2 * math.pi, 48, endpoint=False)
    far = 1e6
    points = np.stack([far + np.cos(t) * (1 + 0.3 * np.cos(3 * t)), np.zeros_like(t), 0.5 * np.sin(t)], axis=1)
    drawing.add_strokes([len(points)])
    drawing.attributes["position"].data.foreach_set("vector", points.astype(np.float32).ravel())
    radius = drawing.attributes.get("radius") or drawing.attributes.new("radius", "FLOAT", "POINT")
    radius.data.foreach_set("value", np.full(len(points), 0.02, np.float32))
    cyclic = drawing.attributes.get("cyclic") or drawing.attributes.new("cyclic", "BOOLEAN", "CURVE")
    cyclic.data.foreach_set("value", np.ones(1, bool))
    bpy.context.view_layer.update()
    checks.select_only(obj)
    rest = checks.evaluated_drawing_points(obj).astype(float).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, rest[0]))
    bpy.context.view_layer.update()
    step = float(np.spacing(np.float32(far)))
    assert np.abs(checks.evaluated_drawing_points(obj) - rest).max() <= 4 * step

