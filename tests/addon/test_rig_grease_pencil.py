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
    # Its strokes are poly lines: the modifier gives them no Bezier handles (its Bezier stages
    # took a third of a still monkey's evaluation, on every frame).
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    names = {a.name for layer in evaluated.data.layers for a in layer.current_frame().drawing.attributes}
    assert not names & {"handle_left", "handle_right", "handle_type_left", "handle_type_right"}, names

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


def test_eyes_drawn_in_a_head_outlined_by_hand_follow_the_head(addon):
    """Line art (a stroke material, no fill): a head drawn as one stroke round to where it
    began, which the draw tool leaves open, and eyes inside. The rig was a thin ring of the
    outline, and the eyes stayed at rest while the head swung 0.6 (QA). What one stroke goes
    round is the shape's, as a closed stroke's is."""
    data = getattr(bpy.data, "grease_pencils_v3", bpy.data.grease_pencils).new("Face")
    obj = bpy.data.objects.new("Face", data)
    bpy.context.scene.collection.objects.link(obj)
    material = bpy.data.materials.new("Line")
    bpy.data.materials.create_gpencil_data(material)
    data.materials.append(material)
    t = np.linspace(0.0, 2 * np.pi + 0.1, 64)
    strokes = [np.column_stack([np.cos(t), 0 * t, np.sin(t)]),
               np.array([(-0.35, 0.0, 0.3), (-0.3, 0.0, 0.35), (-0.25, 0.0, 0.3)]),
               np.array([(0.25, 0.0, 0.3), (0.3, 0.0, 0.35), (0.35, 0.0, 0.3)])]
    drawing = data.layers.new("Lines").frames.new(bpy.context.scene.frame_current).drawing
    drawing.add_strokes([len(points) for points in strokes])
    drawing.attributes["position"].data.foreach_set("vector", np.concatenate(strokes).astype(np.float32).ravel())
    radius = drawing.attributes.get("radius") or drawing.attributes.new("radius", "FLOAT", "POINT")
    radius.data.foreach_set("value", np.full(70, 0.01, np.float32))
    checks.select_only(obj)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    rest = drawing_points(obj, evaluated=False).copy()
    checks.add_handle(obj, checks.world(obj, (0.0, 0.0, -1.0)))
    checks.add_handle(obj, checks.world(obj, (0.0, 0.0, 1.0))).location.x += 0.6
    bpy.context.view_layer.update()
    moved = np.linalg.norm(drawing_points(obj) - rest, axis=1)
    assert moved[:64].max() > 0.5 and moved[64:].min() > 0.1


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

    bpy.ops.object.grease_pencil_add(type="MONKEY")  # hidden by a hidden group it is in (QA: no word)
    grouped = bpy.context.active_object
    outer = grouped.data.layer_groups.new("Reference")
    inner = grouped.data.layer_groups.new("Inner", parent_group=outer)
    grouped.data.layers.move_to_layer_group(grouped.data.layers["Fills"], inner)
    outer.hide = True
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



def body_and_arm(per_side=12, arm_first=False):
    """A grease pencil figure drawn in XZ: a filled body on layer "Body" and a filled arm on
    layer "Arm" above it (below, ``arm_first``), the arm's root drawn over the body."""
    data = getattr(bpy.data, "grease_pencils_v3", bpy.data.grease_pencils).new("Figure")
    obj = bpy.data.objects.new("Figure", data)
    bpy.context.scene.collection.objects.link(obj)
    material = bpy.data.materials.new("Fill")
    bpy.data.materials.create_gpencil_data(material)
    if bpy.app.version < (5, 1):  # 5.1 fills the strokes that have a fill_id
        material.grease_pencil.show_fill = True
    data.materials.append(material)
    outlines = {"Body": [(-1.2, -1.0), (0.2, -1.0), (0.2, 1.0), (-1.2, 1.0)],
                "Arm": [(-0.6, 0.5), (1.6, 0.5), (1.6, 0.9), (-0.6, 0.9)]}
    for name, corners in sorted(outlines.items(), reverse=arm_first):
        drawing = data.layers.new(name).frames.new(bpy.context.scene.frame_current).drawing
        ring = np.array(corners + corners[:1], float)
        points = [a + (b - a) * t for a, b in zip(ring[:-1], ring[1:])
                  for t in np.linspace(0.0, 1.0, per_side, endpoint=False)]
        drawing.add_strokes([len(points)])
        drawing.attributes["position"].data.foreach_set(
            "vector", np.array([(x, 0.0, z) for x, z in points], np.float32).ravel())
        for attribute, kind, value in (("cyclic", "BOOLEAN", True), ("fill_id", "INT", 1)):
            (drawing.attributes.get(attribute) or drawing.attributes.new(attribute, kind, "CURVE")).data[0].value = value
        radius = drawing.attributes.get("radius") or drawing.attributes.new("radius", "FLOAT", "POINT")
        radius.data.foreach_set("value", np.full(len(points), 0.01, np.float32))
    bpy.context.view_layer.objects.active = obj
    return obj


def layer_points(obj, name, evaluated=True):
    if evaluated:
        return checks.evaluated_drawing_points(obj, name).astype(np.float64)
    return checks.drawing_points(obj.data.layers[name].current_frame().drawing).astype(np.float64)


@pytest.mark.parametrize("apart", [True, False])
def test_layers_apart_keep_an_arm_drawn_over_the_body_apart_from_it(addon, tmp_path, apart, quiet):
    """Strokes that overlap at rest join: an arm drawn on its own layer over the body dragged
    the body with it. With Layers Apart each layer is a part of its own (its island, on the
    layers, read by the modifier): the arm swings over a body that stays put, through a save and
    reload; Unbind takes the layers' islands away."""
    obj = body_and_arm()
    obj.shapedeform.layers_apart = apart
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    body, arm = layer_points(obj, "Body", False), layer_points(obj, "Arm", False)
    for corner in ((-1.15, -0.95), (0.15, -0.95), (-1.15, 0.95)):  # the body's, away from the arm
        checks.add_handle(obj, checks.world(obj, (corner[0], 0.0, corner[1])))
    checks.add_handle(obj, checks.world(obj, (0.6, 0.0, 0.7)))  # the arm's, off the body
    tip = checks.add_handle(obj, checks.world(obj, (1.55, 0.0, 0.7)))
    tip.location.z += 0.5
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    assert np.abs(layer_points(obj, "Arm") - arm).max() > 0.3
    body_moved = np.abs(layer_points(obj, "Body") - body).max()
    if not apart:
        assert np.abs(layer_points(obj, "Body") - body)[:, [0, 2]].max() > 0.01  # joined, the body bends with the arm
        assert ".sd_island" not in obj.data.attributes
        return
    assert body_moved < 1e-4
    islands = np.empty(2, np.int32)
    obj.data.attributes[".sd_island"].data.foreach_get("value", islands)
    assert obj.data.attributes[".sd_island"].domain == "LAYER" and sorted(islands) == [1, 2]

    posed = {name: layer_points(obj, name) for name in ("Body", "Arm")}
    path = str(tmp_path / "figure.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Figure"]
    for name, points in posed.items():
        np.testing.assert_allclose(layer_points(obj, name), points, atol=1e-6)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert ".sd_island" not in obj.data.attributes
    np.testing.assert_array_equal(layer_points(obj, "Body"), body)


def test_an_overlap_pin_on_layers_apart_says_the_layers_keep_their_order(addon, capsys):
    """With Layers Apart each layer is drawn whole, in its order: a pin on the arm orders only
    the arm's own strokes (QA: a pin at 1 left an arm layer under the body), and says so; on a
    drawing rigged as one shape it says nothing."""
    for apart in (True, False):
        obj = body_and_arm()
        obj.shapedeform.layers_apart = apart
        assert bpy.ops.shapedeform.bind() == {"FINISHED"}
        capsys.readouterr()
        assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, (1.0, 0.0, 0.7)), kind="OVERLAP") == {
            "FINISHED"}
        assert ("with Layers Apart the layers are drawn in their order" in capsys.readouterr().out) == apart
        bpy.data.objects.remove(obj)


@pytest.mark.parametrize("arm_first, layers, reordered", [(False, "", False), (True, "", False),
                                                          (False, "Arm, Body", False), (True, "Body, Arm", False),
                                                          (False, "", True), (True, "", True)])
def test_a_handle_at_rest_where_layers_overlap_holds_the_layer_drawn_on_top(addon, quiet, arm_first, layers,
                                                                            reordered):
    """With Layers Apart, a handle added in Object Mode where the arm lies over the body at rest
    (both level, in the drawing's plane) holds the layer drawn on top, in whatever order the
    Layers field names them, and after the layers are reordered: it held whichever part's
    triangle came first (and, reordered after Bind, the layer drawn on top at Bind: review)."""
    obj = body_and_arm(arm_first=arm_first)
    obj.shapedeform.layers_apart = True
    obj.shapedeform.layers = layers
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    if reordered:
        obj.data.layers.move_bottom(obj.data.layers[-1])
        bpy.context.view_layer.update()
    top = obj.data.layers[-1].name
    rest = {name: layer_points(obj, name, False) for name in ("Body", "Arm")}
    handle = checks.add_handle(obj, checks.world(obj, (-0.3, 0.0, 0.7)))  # over both
    handle.location.z += 0.3
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    moved = {name: np.abs(layer_points(obj, name) - points).max() for name, points in rest.items()}
    assert moved[top] > 0.25 and moved[({"Body", "Arm"} - {top}).pop()] < 1e-4, (top, moved)


@pytest.mark.parametrize("arm_first", [False, True])
def test_a_handle_at_selected_arm_points_over_the_body_holds_the_arm_alone(addon, quiet, arm_first):
    """With Layers Apart, points selected on the arm where it lies over the body give handles
    that hold the arm (their layer's part), not the body under them."""
    obj = body_and_arm(arm_first=arm_first)
    obj.shapedeform.layers_apart = True
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    body = layer_points(obj, "Body", False)
    for layer in obj.data.layers:
        drawing = layer.current_frame().drawing
        points = checks.drawing_points(drawing)
        selection = drawing.attributes.get(".selection") or drawing.attributes.new(".selection", "BOOLEAN", "POINT")
        # The arm's root, over the body.
        selection.data.foreach_set("value", (layer.name == "Arm") & (points[:, 0] < -0.55))
    islands = np.empty(2, np.int32)
    obj.data.attributes[".sd_island"].data.foreach_get("value", islands)
    arm_island = islands[[layer.name for layer in obj.data.layers].index("Arm")]
    selected = addon.shapedeform_addon.sources.selected_islands(obj)
    assert len(selected) > 2 and np.all(selected == arm_island)
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    checks.add_handle(obj, checks.world(obj, (-1.15, 0.0, -0.95)))  # the body's
    root = obj.shapedeform.handles[0].object
    root.location.z -= 0.3
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    assert np.abs(layer_points(obj, "Arm") - layer_points(obj, "Arm", False)).max() > 0.25
    assert np.abs(layer_points(obj, "Body") - body).max() < 1e-4


def test_a_copy_with_its_handles_keeps_its_layers_apart(addon, quiet):
    """Shift+D of a figure rigged with Layers Apart, with its handles: the copy's rig reads its
    own layers' islands, and its arm swings over a body that stays put, the original's pose
    untouched."""
    obj = body_and_arm()
    obj.shapedeform.layers_apart = True
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, (-1.15, 0.0, -0.95)))
    checks.add_handle(obj, checks.world(obj, (0.6, 0.0, 0.7)))
    checks.add_handle(obj, checks.world(obj, (1.55, 0.0, 0.7)))
    posed = {name: layer_points(obj, name) for name in ("Body", "Arm")}
    checks.select_only(obj)
    for item in obj.shapedeform.handles:
        item.object.select_set(True)
    assert bpy.ops.object.duplicate() == {"FINISHED"}
    copy = bpy.context.active_object
    bpy.context.view_layer.update()
    assert copy.data != obj.data and copy.shapedeform.cage != obj.shapedeform.cage

    def islands(data):
        values = np.empty(len(data.attributes[".sd_island"].data), np.int32)
        data.attributes[".sd_island"].data.foreach_get("value", values)
        return values

    assert set(islands(copy.data)) == set(islands(copy.shapedeform.cage.data)) == {1, 2}
    body = layer_points(copy, "Body", False)
    copy.shapedeform.handles[2].object.location.z += 0.5
    bpy.context.view_layer.update()
    assert copy.shapedeform.status == ""
    assert np.abs(layer_points(copy, "Arm") - layer_points(copy, "Arm", False)).max() > 0.3
    assert np.abs(layer_points(copy, "Body") - body).max() < 1e-4
    for name, points in posed.items():
        np.testing.assert_allclose(layer_points(obj, name), points, atol=1e-6)


def test_a_second_rig_of_the_drawing_keeps_the_first_rigs_layers_apart(addon, quiet):
    """An Alt+D copy of a figure rigged with Body and Arm apart, released and bound with Leg
    and Body apart: both rigs read one attribute of the layers' islands, which the copy's Bind
    made anew with its own numbers, so the first rig's arm lost its island and moved 0.24 with
    no word (QA). The layers keep the numbers they have; a layer new to layers apart gets the
    next. Unbinding the copy leaves the first rig's pose as it was."""
    obj = body_and_arm()
    data = obj.data
    drawing = data.layers.new("Leg").frames.new(bpy.context.scene.frame_current).drawing
    leg = np.array([(-0.6, 0.0, -0.8), (-0.6, 0.0, -2.5), (-0.3, 0.0, -2.5), (-0.3, 0.0, -0.8)], np.float32)
    drawing.add_strokes([4])
    drawing.attributes["position"].data.foreach_set("vector", leg.ravel())
    for attribute, kind, value in (("cyclic", "BOOLEAN", True), ("fill_id", "INT", 1)):
        (drawing.attributes.get(attribute) or drawing.attributes.new(attribute, kind, "CURVE")).data[0].value = value
    obj.shapedeform.layers_apart, obj.shapedeform.layers = True, "Body, Arm"
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, (-1.15, 0.0, -0.95)))
    checks.add_handle(obj, checks.world(obj, (0.6, 0.0, 0.7)))
    checks.add_handle(obj, checks.world(obj, (1.55, 0.0, 0.7))).location.z += 0.5
    bpy.context.view_layer.update()
    posed = {name: layer_points(obj, name) for name in ("Body", "Arm")}
    assert np.abs(posed["Arm"] - layer_points(obj, "Arm", False)).max() > 0.3

    checks.select_only(obj)
    assert bpy.ops.object.duplicate(linked=True) == {"FINISHED"}
    copy = bpy.context.active_object
    assert copy.data == data
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}  # Stop Following
    copy.shapedeform.layers_apart, copy.shapedeform.layers = True, "Leg, Body"
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(copy, checks.world(copy, (-0.45, 0.0, -2.4))).location.x += 0.5
    checks.add_handle(copy, checks.world(copy, (-1.15, 0.0, 0.95)))
    bpy.context.view_layer.update()
    assert copy.shapedeform.status == "" and obj.shapedeform.status == ""
    for name, points in posed.items():
        np.testing.assert_allclose(layer_points(obj, name), points, atol=1e-5)
    assert np.abs(layer_points(copy, "Leg") - leg).max() > 0.3

    checks.select_only(copy)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    bpy.context.view_layer.update()
    for name, points in posed.items():
        np.testing.assert_allclose(layer_points(obj, name), points, atol=1e-5)

    # Where the body (numbered between the arm and the leg) has nothing drawn, the copy's rig
    # would number its parts about the body's.
    data.layers["Body"].frames.new(bpy.context.scene.frame_current + 4)
    bpy.context.scene.frame_set(bpy.context.scene.frame_current + 4)
    copy.shapedeform.layers = "Arm, Body, Leg"
    with pytest.raises(RuntimeError, match="its layer 'Body', kept apart by the rig of 'Figure'"):
        bpy.ops.shapedeform.bind()
    assert not copy.shapedeform.is_bound


@pytest.mark.parametrize("joined", ["a stroke", "a figure with layers apart"])
def test_a_drawing_joined_into_a_figure_with_layers_apart_keeps_its_parts(addon, quiet, joined):
    """Ctrl+J of another grease pencil into a figure rigged with Layers Apart: Join merges the
    layers' attributes out of order (see keep_marks), and the figure's layers must keep their
    own islands: the arm still swings over a body that stays put."""
    obj = body_and_arm()
    obj.shapedeform.layers_apart = True
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    for corner in ((-1.15, -0.95), (0.15, -0.95)):
        checks.add_handle(obj, checks.world(obj, (corner[0], 0.0, corner[1])))
    checks.add_handle(obj, checks.world(obj, (0.6, 0.0, 0.7)))
    tip = checks.add_handle(obj, checks.world(obj, (1.55, 0.0, 0.7)))
    if joined == "a stroke":
        bpy.ops.object.grease_pencil_add(type="STROKE", location=(3.0, 0.0, 0.0))
        other = bpy.context.active_object
    else:
        other = body_and_arm()
        other.location.x = 3.0
        other.shapedeform.layers_apart = True
        assert bpy.ops.shapedeform.bind() == {"FINISHED"}
        checks.add_handle(other, checks.world(other, (-1.15, 0.0, -0.95)))
        checks.add_handle(other, checks.world(other, (1.55, 0.0, 0.7))).location.z -= 0.3
        bpy.context.view_layer.update()
    checks.select_only(obj)
    other.select_set(True)
    assert bpy.ops.object.join() == {"FINISHED"}
    bpy.context.view_layer.update()
    body = layer_points(obj, "Body", False)
    tip.location.z += 0.5
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    assert np.abs(layer_points(obj, "Arm") - layer_points(obj, "Arm", False)).max() > 0.3
    assert np.abs(layer_points(obj, "Body") - body).max() < 1e-4


def test_a_bezier_strokes_handles_turn_with_its_part(addon):
    """A stroke made Bezier (Set Curve Type), its handles Aligned as after editing one by hand,
    turned by its only handle: the drawing turns rigidly, its Bezier handles included (they
    were moved along with their points but kept their rest directions, 0.18 off at 1.5 rad on
    an ellipse 2 wide, and the drawn line bent)."""
    from mathutils import Matrix

    bpy.ops.object.grease_pencil_add(type="EMPTY")
    obj = bpy.context.active_object
    layer = obj.data.layers[0] if len(obj.data.layers) else obj.data.layers.new("Lines")
    drawing = (layer.current_frame() or layer.frames.new(bpy.context.scene.frame_current)).drawing
    drawing.add_strokes([12])
    turns = np.linspace(0.0, 2.0 * np.pi, 12, endpoint=False)
    ellipse = np.stack([np.cos(turns), np.zeros(12), 0.4 * np.sin(turns)], axis=1)
    drawing.attributes["position"].data.foreach_set("vector", ellipse.astype(np.float32).ravel())
    drawing.attributes.new("cyclic", "BOOLEAN", "CURVE").data[0].value = True
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.grease_pencil.select_all(action="SELECT")
    bpy.ops.grease_pencil.set_curve_type(type="BEZIER")
    bpy.ops.grease_pencil.set_handle_type(type="ALIGN")
    bpy.ops.object.mode_set(mode="OBJECT")

    def points(evaluated):
        source = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data if evaluated else obj.data
        attributes = source.layers[0].current_frame().drawing.attributes
        return np.stack([checks.attribute_vectors(attributes, name, 12) for name in ("position", "handle_left",
                                                                                      "handle_right")])

    rest = points(False)
    assert np.abs(rest[1] - rest[0]).max() > 0.05  # the handles reach out from their points
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    handle = checks.add_handle(obj, (0.0, 0.0, 0.0))
    handle.rotation_euler.y += 1.5
    bpy.context.view_layer.update()
    turn = np.array(Matrix.Rotation(1.5, 3, "Y"))
    np.testing.assert_allclose(points(True), rest @ turn.T, atol=1e-4)
