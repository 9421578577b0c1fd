# SPDX-License-Identifier: GPL-3.0-or-later
"""Where a pose folds the shape over itself, one layer renders in front, cleanly (issue 14).

A figure (a torso and an arm, each its own material colour) has its arm dragged across its
torso; the scene is rendered headless and the pixels where the evaluated arm and torso both lie
are read back: one part's colour fills them, the same on consecutive frames of the motion."""

import addon_utils
import bpy
import numpy as np
import pytest

from extension_under_test import ADDON_MODULE

import renders
import rig_checks as checks

TORSO, ARM = (0.1, 0.2, 0.9, 1.0), (0.9, 0.15, 0.1, 1.0)
SIZE = 160


def figure():
    """A flat figure: a torso (x in [-0.3, 0.3], y in [-1, 1]) and an arm to its right.

    Returns the object and, per face, whether it is the arm's."""
    step = 0.1
    xs, ys = np.arange(-0.3, 1.6 + 1e-9, step), np.arange(-1.0, 1.0 + 1e-9, step)
    index = {(i, j): k for k, (j, i) in enumerate(np.ndindex(len(ys), len(xs)))}
    verts = [(x, y, 0.0) for y in ys for x in xs]
    faces, arm = [], []
    for (i, j), k in index.items():
        if i + 1 >= len(xs) or j + 1 >= len(ys):
            continue
        cx, cy = xs[i] + step / 2, ys[j] + step / 2
        in_torso, in_arm = cx < 0.3, 0.5 < cy < 0.8
        if in_torso or in_arm:
            quad = [k, index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]]
            faces += [quad[:3], [quad[0], quad[2], quad[3]]]
            arm += [not in_torso] * 2
    mesh = bpy.data.meshes.new("Figure")
    mesh.from_pydata(verts, [], faces)
    mesh.validate()
    for colour in (TORSO, ARM):
        mesh.materials.append(renders.flat_material("Torso" if colour == TORSO else "Arm", colour))
    mesh.polygons.foreach_set("material_index", np.array(arm, dtype=np.int32))
    obj = bpy.data.objects.new("Figure", mesh)
    obj["forearm_from_x"] = 0.8  # the arm's faces beyond this x, in the tests' pin checks
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    # Drop vertices on no face (the grid's corners beside the arm).
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.mesh.delete_loose()
    bpy.ops.object.mode_set(mode="OBJECT")
    return obj, np.array(arm)


def swing_arm_across(obj):
    """Bind, hold the torso, and key the arm's tip from its rest place (frame 1) across the
    torso (frame 10)."""
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, (0.0, -0.8, 0.0))
    checks.add_handle(obj, (0.0, 0.3, 0.0))
    tip = checks.add_handle(obj, (1.5, 0.65, 0.0))
    tip.keyframe_insert("location", frame=1)
    tip.keyframe_insert("rotation_euler", frame=1)
    tip.location = (-0.75, 0.45, 0.0)
    tip.rotation_euler.z = 3.0
    tip.keyframe_insert("location", frame=10)
    tip.keyframe_insert("rotation_euler", frame=10)
    return tip


def swung_figure():
    """The figure with its arm swung across the torso, at frame 10: (object, per face whether
    it is the arm's, rest points (n, 3), points as posed (n, 3))."""
    obj, arm = figure()
    swing_arm_across(obj)
    bpy.context.scene.frame_set(10)
    return obj, arm, checks.mesh_points(obj), checks.evaluated_mesh_points(obj)


def forearm_over_torso(rest, posed):
    """Indices of the forearm's points (whose handle regions do not reach the shoulder) that
    the pose lays over the torso."""
    return np.flatnonzero((rest[:, 0] > 0.8) & (np.abs(posed[:, 0]) < 0.2) & (np.abs(posed[:, 1]) < 0.9))


def part_shares(obj, arm, camera, pixels, torso=None, margin=None):
    """(arm share, torso share) of the pixels where the evaluated arm and torso overlap, at least
    ``margin`` inside (1.5 pixels by default)."""
    torso = ~arm if torso is None else torso
    margin = 1.5 * camera.data.ortho_scale / SIZE if margin is None else margin
    overlap = renders.overlap_pixels(camera, SIZE, renders.covered(obj, arm), renders.covered(obj, torso),
                                     margin=margin)
    assert overlap.sum() > 50, "the pose does not overlap the arm with the torso"
    return shares(pixels[overlap])


def shares(pixels):
    """(arm share, torso share) of ``pixels`` (k, 4): red-dominated is the arm, blue the torso."""
    red, blue = pixels[:, 0], pixels[:, 2]
    return float(np.mean(red > blue + 0.3)), float(np.mean(blue > red + 0.3))


@pytest.mark.parametrize("engine", ["BLENDER_WORKBENCH", "CYCLES", "EEVEE"])
def test_with_no_pin_the_arm_dragged_across_renders_in_front_on_consecutive_frames(addon, tmp_path, engine):
    obj, arm = figure()
    swing_arm_across(obj)
    camera = renders.camera_over((0.4, 0.0), 2.6)
    scene = bpy.context.scene
    for frame in (8, 9, 10):
        scene.frame_set(frame)
        pixels = renders.render(tmp_path / f"frame{frame}.png", engine=engine, size=SIZE)
        arm_share, torso_share = part_shares(obj, arm, camera, pixels)
        assert arm_share >= 0.97, f"frame {frame}: arm {arm_share:.3f}, torso {torso_share:.3f}"


def test_a_perspective_camera_sees_the_same_layer_in_front(addon, tmp_path):
    obj, arm = figure()
    swing_arm_across(obj)
    bpy.context.scene.frame_set(10)
    ortho = renders.camera_over((0.4, 0.0), 2.6)
    expected = renders.overlap_pixels(ortho, SIZE, renders.covered(obj, arm), renders.covered(obj, ~arm),
                                      margin=3 * 2.6 / SIZE)
    renders.camera_over((0.4, 0.0), 2.6, perspective=True)
    pixels = renders.render(tmp_path / "perspective.png", size=SIZE)
    # At this distance the perspective view is within a pixel or two of the orthographic one
    # over the overlap (the margin above), where every pixel must show the arm.
    assert shares(pixels[expected])[0] >= 0.97


def forearm(obj, arm):
    """Per face: the arm's faces beyond the elbow. Where the arm folds over at the shoulder,
    the arm and the torso are the same distance from any pin; the forearm is what pins judge."""
    centres = np.array([p.center.x for p in obj.data.polygons])
    return arm & (centres > obj["forearm_from_x"])


def render_overlap(obj, arm, tmp_path, name, engine="BLENDER_WORKBENCH"):
    """(forearm share, torso share) where the forearm lies over the torso, rendered."""
    camera = renders.camera_over((0.4, 0.0), 2.6)
    pixels = renders.render(tmp_path / f"{name}.png", engine=engine, size=SIZE)
    return part_shares(obj, forearm(obj, arm), camera, pixels, ~arm)


# EEVEE draws coplanar faces last-drawn-in-front (the arm here, with no depth at all), so its
# case is the pin at -1 putting the torso in front.
@pytest.mark.parametrize("engine", ["BLENDER_WORKBENCH", "EEVEE"])
def test_overlap_pins_put_the_pinned_part_in_front_or_behind_and_key_between(addon, tmp_path, engine):
    obj, arm = figure()
    swing_arm_across(obj)
    scene = bpy.context.scene
    scene.frame_set(10)
    before = checks.evaluated_mesh_points(obj)[:, :2].copy()
    assert render_overlap(obj, arm, tmp_path, "no_pin", engine)[0] >= 0.97  # by default the arm
    bpy.context.view_layer.objects.active = obj
    # The pin goes where the hand is now, and binds to the rest point under it.
    hand = checks.evaluated_mesh_points(obj)[np.argmin(np.linalg.norm(checks.mesh_points(obj)[:, :2] - [1.4, 0.65], axis=1))]
    assert bpy.ops.shapedeform.add_handle(location=tuple(hand), kind="OVERLAP") == {"FINISHED"}
    pin = obj.shapedeform.handles[-1].object
    assert pin.shapedeform.pin_kind == "OVERLAP" and pin.shapedeform.in_front == 1.0
    assert pin.parent == obj.shapedeform.cage and pin.parent_type == "VERTEX"
    np.testing.assert_allclose(np.array(pin.matrix_world.translation)[:2], hand[:2], atol=0.08)  # on the hand
    pin.shapedeform.extent = 0.3
    # A pin pulls nothing: the shape stays where it was.
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj)[:, :2], before, atol=1e-6)
    arm_share, torso_share = render_overlap(obj, arm, tmp_path, "hand_pinned_in_front", engine)
    assert arm_share >= 0.97, f"hand pinned +1: arm {arm_share:.3f}, torso {torso_share:.3f}"
    pin.shapedeform.in_front = -1.0
    arm_share, torso_share = render_overlap(obj, arm, tmp_path, "hand_pinned_behind", engine)
    assert torso_share >= 0.97, f"hand pinned -1: arm {arm_share:.3f}, torso {torso_share:.3f}"

    # Keyed: behind at frame 9, in front at frame 10.
    pin.shapedeform.in_front = -1.0
    pin.keyframe_insert('shapedeform.in_front', frame=9)
    pin.shapedeform.in_front = 1.0
    pin.keyframe_insert('shapedeform.in_front', frame=10)
    scene.frame_set(9)
    assert render_overlap(obj, arm, tmp_path, "keyed9", engine)[1] >= 0.97  # behind the body
    scene.frame_set(10)
    assert render_overlap(obj, arm, tmp_path, "keyed10", engine)[0] >= 0.97  # in front of it


def test_a_pin_added_where_the_pose_overlaps_itself_goes_on_the_layer_clicked(addon):
    """Clicked on the arm where it lies over the torso (the arm's place, in front), an overlap
    pin binds to the arm: it was bound to whichever layer's triangle the triangulation gave
    first, the torso's at all 11 such places tried, so -1 sank the torso and +1 lifted it over
    the arm. Clicked on the torso beside it, under the arm, it binds to the torso."""
    obj, arm, rest, posed = swung_figure()
    on_arm = (rest[:, 0] > 0.45) & (rest[:, 1] > 0.55) & (rest[:, 1] < 0.75)
    over_torso = on_arm & (np.abs(posed[:, 0]) < 0.2) & (np.abs(posed[:, 1]) < 0.9)
    assert over_torso.sum() >= 4
    torso = rest[:, 0] < 0.25
    rest_of = addon.shapedeform_addon.rig_format.rest_of(obj.shapedeform.cage)
    for k in np.flatnonzero(over_torso)[:6]:
        below = np.flatnonzero(torso)[np.argmin(np.linalg.norm(posed[torso, :2] - posed[k, :2], axis=1))]
        for location, on_the_arm in ((posed[k], True), (posed[below], False)):
            checks.select_only(obj)
            assert bpy.ops.shapedeform.add_handle(location=tuple(location), kind="OVERLAP") == {"FINISHED"}
            pin = obj.shapedeform.handles[-1]
            point = pin[addon.shapedeform_addon.rig_format.PIN_POINT]
            pin.object.shapedeform.in_front = 0.0  # the next place is clicked on the same layers
            bpy.context.view_layer.update()
            # The torso's right edge (x = 0.3) is the shoulder's seam, on both parts.
            assert (rest_of[point, 0] > 0.35 if on_the_arm else rest_of[point, 0] <= 0.3 + 1e-6), (k, rest_of[point])


def test_render_animation_and_drivers_follow_an_overlap_pins_amount(addon, tmp_path):
    """Keyed behind at frame 9 and in front at frame 10, a pinned hand renders in front at
    frame 10 of Render Animation, as a farm runs it (a render's depsgraph keeps the frame's
    amount in its evaluated copies only: the hand rendered at the amount of the frame the render
    started from). Driven, the amount poses at once (it waited for the next frame change)."""
    obj, arm = figure()
    swing_arm_across(obj)
    scene = bpy.context.scene
    scene.frame_set(10)
    rest = checks.mesh_points(obj)
    hand = int(np.argmin(np.linalg.norm(rest[:, :2] - [1.4, 0.65], axis=1)))
    bpy.context.view_layer.objects.active = obj
    location = tuple(checks.evaluated_mesh_points(obj)[hand])
    assert bpy.ops.shapedeform.add_handle(location=location, kind="OVERLAP") == {"FINISHED"}
    pin = obj.shapedeform.handles[-1].object
    pin.shapedeform.extent = 0.3
    pin.shapedeform.in_front = -1.0
    pin.keyframe_insert("shapedeform.in_front", frame=9)
    pin.shapedeform.in_front = 1.0
    pin.keyframe_insert("shapedeform.in_front", frame=10)
    camera = renders.camera_over((0.4, 0.0), 2.6)
    pixels = renders.animation_frame(10, tmp_path, "farm", size=SIZE)
    scene.frame_set(10)
    arm_share, torso_share = part_shares(obj, forearm(obj, arm), camera, pixels, ~arm)
    assert arm_share >= 0.97, f"frame 10 of an animation render: arm {arm_share:.3f}, torso {torso_share:.3f}"

    pin.animation_data_clear()
    pin.shapedeform.in_front = 1.0
    in_front = checks.evaluated_mesh_points(obj)[hand, 2]
    pin.shapedeform.in_front = -1.0
    behind = checks.evaluated_mesh_points(obj)[hand, 2]
    assert in_front > behind
    control = bpy.data.objects.new("Control", None)
    scene.collection.objects.link(control)
    control.location.x = -1.0
    driver = pin.driver_add("shapedeform.in_front").driver
    driver.type = "AVERAGE"
    variable = driver.variables.new()
    variable.type = "TRANSFORMS"
    variable.targets[0].id = control
    variable.targets[0].transform_type = "LOC_X"
    bpy.context.view_layer.update()
    control.location.x = 1.0  # the slider a driver reads
    bpy.context.view_layer.update()
    assert pin.shapedeform.in_front == 1.0
    assert checks.evaluated_mesh_points(obj)[hand, 2] == pytest.approx(in_front, abs=1e-6)


def stroke_heights(obj, layer, normal):
    """Mean height along ``normal`` of each stroke of a layer's evaluated drawing, in its order."""
    geometry = evaluated_geometry(obj)  # owns the drawing: keep it while reading
    drawing = geometry.grease_pencil.layers[layer].current_frame().drawing
    points = checks.drawing_points(drawing) @ np.asarray(normal, float)
    offsets = np.empty(len(drawing.curve_offsets), np.int32)
    drawing.curve_offsets.foreach_get("value", offsets)
    return np.array([points[a:b].mean() for a, b in zip(offsets[:-1], offsets[1:])])


def evaluated_geometry(obj):
    return obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).evaluated_geometry()


ORDER = "test_rest_order"


def number_strokes(obj):
    """Give each stroke of the current drawings its index as a curve attribute (``ORDER``)."""
    for layer in obj.data.layers:
        drawing = layer.current_frame().drawing
        count = len(drawing.curve_offsets) - 1
        drawing.attributes.new(ORDER, "INT", "CURVE").data.foreach_set("value", np.arange(count, dtype=np.int32))
    obj.data.update_tag()


def drawn_order(obj, layer):
    """The ``ORDER`` of each stroke of a layer's evaluated drawing, in the order they draw
    (a layer Stroke Order draws as several layers of its name, one after the other)."""
    geometry = evaluated_geometry(obj)  # owns the drawing: keep it while reading
    orders = []
    for part in geometry.grease_pencil.layers:
        if part.name == layer:
            attribute = part.current_frame().drawing.attributes.get(ORDER)
            orders.append(np.empty(len(attribute.data) if attribute else 0, np.int32))
            if attribute:
                attribute.data.foreach_get("value", orders[-1])
    return np.concatenate(orders)


def test_grease_pencil_strokes_over_a_fold_draw_after_the_rest(addon):
    """Stroke Order, as bind sets it for a drawing that loses nothing by it. The monkey's ear
    flapped outwards covers nothing and reorders nothing, although it moved far further than
    the face (sorting every stroke by its height drew the face's fill over the eyes). A figure's
    arm folded over its body draws after the eye drawn on the body; the body and the eye keep
    their order. Turned off, the drawing's order stands."""
    obj, ear = monkey_seen_from_the_front()
    assert addon.shapedeform_addon.compat.modifier_input(*stroke_order_input(addon, obj)) is True
    number_strokes(obj)
    ear.location.x -= 0.2  # outwards: no part of the shape covers another
    bpy.context.view_layer.update()
    front = (0.0, -1.0, 0.0)  # drawn in XZ, seen from -Y
    for layer in ("Fills", "Lines"):
        order = drawn_order(obj, layer)
        assert list(order) == sorted(order), layer
        # Nor is anything lifted: the automatic order applies only where the pose overlaps
        # itself (the ear was lifted over 1e-3 all the same).
        assert np.abs(stroke_heights(obj, layer, front)).max() < 1e-6

    figure, tip = figure_seen_from_the_front()
    assert addon.shapedeform_addon.compat.modifier_input(*stroke_order_input(addon, figure)) is True
    number_strokes(figure)
    tip.location.x -= 2.0  # the arm over the body and its eye
    bpy.context.view_layer.update()
    body, arm, eye = range(3)
    assert list(drawn_order(figure, "Fills")) == [body, eye, arm]
    set_stroke_order(addon, figure, False)
    assert list(drawn_order(figure, "Fills")) == [body, arm, eye]


def test_strokes_drawn_off_the_plane_beside_the_shape_keep_their_order_when_nothing_folds(addon):
    """Review: strokes drawn after Bind beside the figure, off its plane (one in front, one
    behind), counted as over and under a fold in a pose that folds nothing, and split the
    layer in three (losing its groups and other drawings while the stroke is moved) where
    Stroke Order's rays, missing the cage, had found nothing."""
    figure, tip = figure_seen_from_the_front()
    drawing = figure.data.layers["Fills"].current_frame().drawing
    first = len(drawing.attributes["position"].data)
    drawing.add_strokes([4, 4])
    square = [(2.5, -0.2), (2.9, -0.2), (2.9, 0.2), (2.5, 0.2)]
    beside = np.array([(x, y, z) for y in (-0.05, 0.05) for x, z in square], np.float32)
    positions = np.empty(3 * len(drawing.attributes["position"].data), np.float32)
    drawing.attributes["position"].data.foreach_get("vector", positions)
    positions[3 * first:] = beside.ravel()
    drawing.attributes["position"].data.foreach_set("vector", positions)
    number_strokes(figure)
    tip.location.z += 0.1  # the arm raised a little: nothing folds
    bpy.context.view_layer.update()
    geometry = evaluated_geometry(figure)  # owns the drawings: keep it while reading
    assert [layer.name for layer in geometry.grease_pencil.layers] == ["Fills"]
    assert list(drawn_order(figure, "Fills")) == list(range(5))


def test_an_eye_mostly_under_a_folded_arm_stays_on_the_body(addon, tmp_path):
    """The arm folded over most of the eye drawn on the body: the eye is under a fold, but on the
    body, which has not sunk behind its plane; it stays drawn after the body, and its part the
    arm leaves uncovered shows (drawn first, under every other stroke, the body hid it whole:
    no white pixel; so did a hole cut in the body)."""
    figure, tip = figure_seen_from_the_front()
    number_strokes(figure)
    tip.location.x -= 2.0
    tip.location.z -= 0.2
    bpy.context.view_layer.update()
    body, arm, eye = range(3)
    assert list(drawn_order(figure, "Fills")) == [body, eye, arm]
    on, off = rendered_with_and_without_order(addon, figure, tmp_path)
    assert 20 < eye_white(on) < 0.5 * eye_white(off), (eye_white(on), eye_white(off))  # partly covered


def test_stroke_order_leaves_the_layers_the_rig_does_not_deform_alone(addon):
    """Only "Fills" rigged: the unrigged layer's card and the sticker drawn on it keep their
    order while the arm folds over the body (lying at rest under the lifted cage, both counted
    as under a fold, and the card drew over its sticker)."""
    figure, tip = figure_seen_from_the_front(overlay=True)
    assert addon.shapedeform_addon.compat.modifier_input(*stroke_order_input(addon, figure)) is True
    number_strokes(figure)
    tip.location.x -= 2.0
    bpy.context.view_layer.update()
    assert list(drawn_order(figure, "Fills")) == [0, 2, 1]  # the arm over the body and its eye
    assert list(drawn_order(figure, "Overlay")) == [0, 1]


def test_a_grease_pencil_overlap_pin_puts_the_arm_in_front_or_behind(addon):
    """An overlap pin on the figure's arm, folded over its body: at +1 the arm draws last, at
    -1 first, under the body drawn as one large stroke (which lies mostly outside the fold, so
    only the arm's being under it can move anything: the arm stayed after the body)."""
    figure, tip = figure_seen_from_the_front()
    number_strokes(figure)
    tip.location.x -= 2.0  # the arm over the body and its eye
    bpy.context.view_layer.update()
    bpy.context.view_layer.objects.active = figure
    assert bpy.ops.shapedeform.add_handle(location=tuple(tip.matrix_world.translation), kind="OVERLAP") == {"FINISHED"}
    pin = figure.shapedeform.handles[-1].object
    body, arm, eye = range(3)
    # However large the amount (-150 and +100 inverted the order: the lift left the reach of the
    # rays that read the layers), and however the pins add up.
    for amount, order in ((1.0, [body, eye, arm]), (-1.0, [arm, body, eye]), (1.0, [body, eye, arm]),
                          (-1000.0, [arm, body, eye]), (1000.0, [body, eye, arm])):
        pin.shapedeform.in_front = amount
        bpy.context.view_layer.update()
        assert list(drawn_order(figure, "Fills")) == order, amount
    assert np.all(np.isfinite(checks.evaluated_drawing_points(figure)))
    pin.shapedeform.in_front = float("nan")  # only Python can: named, the last pose kept
    bpy.context.view_layer.update()
    assert f"'{pin.name}': its In Front is not a finite number" in figure.shapedeform.status
    assert np.all(np.isfinite(checks.evaluated_drawing_points(figure)))


def figure_seen_from_the_front(overlay=False):
    """A grease-pencil figure drawn in XZ, unlit, seen from the front: a red body, a white eye
    drawn on it, and a blue arm (its own stroke) reaching out to the right; bound, with handles
    on the body's left edge and the arm's tip. Returns the object and the tip's handle.

    With ``overlay``, a layer "Overlay" above holds a card with a sticker drawn on it over the
    body's left edge, and only "Fills" is rigged."""
    # Blender 4.5 keeps grease pencil v3 data apart from the legacy kind; 5.0 has only v3.
    data = getattr(bpy.data, "grease_pencils_v3", bpy.data.grease_pencils).new("Figure")
    layer = data.layers.new("Fills")
    drawing = layer.frames.new(bpy.context.scene.frame_current).drawing
    obj = bpy.data.objects.new("Figure", data)
    bpy.context.scene.collection.objects.link(obj)
    obj.use_grease_pencil_lights = False
    outlines = {  # x, z corners, in drawing order: the eye is drawn on the body
        "Body": [(-1.2, -1.0), (0.2, -1.0), (0.2, 1.0), (-1.2, 1.0)],
        "Arm": [(0.2, 0.5), (1.6, 0.5), (1.6, 0.9), (0.2, 0.9)],
        "Eye": [(-0.7, 0.3), (-0.3, 0.3), (-0.3, 0.7), (-0.7, 0.7)],
    }
    colours = {"Body": (0.8, 0.1, 0.1, 1.0), "Arm": (0.1, 0.2, 0.9, 1.0), "Eye": (1.0, 1.0, 1.0, 1.0)}
    per_side = 12
    points = []
    for corners in outlines.values():
        ring = np.array(corners + corners[:1], float)
        for a, b in zip(ring[:-1], ring[1:]):
            points.extend(a + (b - a) * t for t in np.linspace(0.0, 1.0, per_side, endpoint=False))
    drawing.add_strokes([4 * per_side] * len(outlines))
    xyz = np.array([(x, 0.0, z) for x, z in points], np.float32)
    drawing.attributes["position"].data.foreach_set("vector", xyz.ravel())
    # Closed, each in its own material; Blender 5.1 fills a stroke that has a fill_id (and
    # hide_stroke leaves out its outline), earlier versions fill by material.
    count = len(outlines)
    for name, kind, values in (("cyclic", "BOOLEAN", [True] * count), ("material_index", "INT", range(count)),
                               ("fill_id", "INT", range(1, count + 1)), ("hide_stroke", "BOOLEAN", [True] * count)):
        attribute = drawing.attributes.get(name) or drawing.attributes.new(name, kind, "CURVE")
        attribute.data.foreach_set("value", list(values))
    radius = drawing.attributes.get("radius") or drawing.attributes.new("radius", "FLOAT", "POINT")
    radius.data.foreach_set("value", np.full(len(xyz), 0.01, np.float32))
    for name, colour in colours.items():
        material = bpy.data.materials.new(name)
        bpy.data.materials.create_gpencil_data(material)
        material.grease_pencil.show_fill, material.grease_pencil.show_stroke = True, False
        material.grease_pencil.fill_color = colour
        data.materials.append(material)
    if overlay:
        card = data.layers.new("Overlay").frames.new(bpy.context.scene.frame_current).drawing
        card.add_strokes([4, 4])
        corners = [(-1.3, -0.95), (-0.9, -0.95), (-0.9, 0.3), (-1.3, 0.3), (-1.2, 0.0), (-1.0, 0.0), (-1.0, 0.2), (-1.2, 0.2)]
        card.attributes["position"].data.foreach_set("vector", np.array([(x, 0.0, z) for x, z in corners], np.float32).ravel())
        obj.shapedeform.layers = "Fills"
    front_camera()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, [-1.2, 0.0, -0.9]))
    checks.add_handle(obj, checks.world(obj, [-1.2, 0.0, 0.9]))
    return obj, checks.add_handle(obj, checks.world(obj, [1.55, 0.0, 0.7]))


def front_camera():
    data = bpy.data.cameras.new("Front")
    data.type, data.ortho_scale = "ORTHO", 3.2
    camera = bpy.data.objects.new("Front", data)
    camera.location, camera.rotation_euler = (0.3, -8.0, 0.0), (np.pi / 2, 0.0, 0.0)
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera


def monkey_seen_from_the_front():
    """The grease-pencil monkey bound, a camera in front, handles on the chin and both ears;
    returns the object and the left ear's handle."""
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    front_camera()
    rest = checks.drawing_points(obj.data.layers["Lines"].current_frame().drawing)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, rest[np.argmin(rest[:, 2])]))  # chin
    checks.add_handle(obj, checks.world(obj, rest[np.argmax(rest[:, 0])]))  # other ear
    return obj, checks.add_handle(obj, checks.world(obj, rest[np.argmin(rest[:, 0])]))


def test_bind_turns_stroke_order_on_where_the_drawing_loses_nothing_by_it(addon):
    """Stroke Order keeps a layer's settings (lighting, blend mode, view-layer filter, parent),
    and renders have no onion skins: bind turns it on unless a layer is masked or keyed before
    frame 0, or a modifier after the rig's reads keyframe timing or filters by layer group, and
    the sidebar says what it drops."""
    losses = addon.shapedeform_addon.sources.grease_pencil.stroke_order_losses

    def bound(setup):
        bpy.ops.object.grease_pencil_add(type="MONKEY")
        obj = bpy.context.active_object
        setup(obj, obj.data.layers["Fills"], obj.data.layers["Lines"])
        found = losses(obj)
        assert bpy.ops.shapedeform.bind() == {"FINISHED"}
        return found, addon.shapedeform_addon.compat.modifier_input(*stroke_order_input(addon, obj))

    def settings(obj, fills, lines):
        lines.blend_mode = "MULTIPLY"
        lines.viewlayer_render = bpy.context.view_layer.name
        lines.parent = bpy.data.objects.new("Parent", None)
        lines.frames.copy(lines.frames[0].frame_number, 5)  # a second keyframe, shown as an onion skin

    assert bound(lambda obj, fills, lines: None) == ([], True)  # Blender's default, lit
    assert bound(settings) == ([], True)

    def masked(obj, fills, lines):
        obj.data.layers.active = fills
        assert bpy.ops.grease_pencil.layer_mask_add(name=lines.name) == {"FINISHED"}  # mask_layers.add: 5.2 on
        fills.use_masks = True

    def early(obj, fills, lines):  # rebuilt drawings are keyed at frame 0: before it, nothing
        for layer in (fills, lines):
            layer.frames.move(layer.frames[0].frame_number, -20)

    assert bound(masked) == (["masks of 'Fills'"], False)
    assert bound(early) == (["drawings before frame 0 of 'Fills', 'Lines'"], False)

    if hasattr(bpy.types.GreasePencilv3Layers, "move_to_layer_group"):  # 4.5's Python cannot group a layer
        def grouped(obj, fills, lines):  # a layer group alone draws the same
            obj.data.layers.move_to_layer_group(lines, obj.data.layer_groups.new("Outlines"))

        def filtered(obj, fills, lines):  # a later modifier filtered by the group would find none
            grouped(obj, fills, lines)
            tint = obj.modifiers.new("Tint", "GREASE_PENCIL_TINT")
            tint.tree_node_filter, tint.use_layer_group_filter = "Outlines", True

        assert bound(grouped) == ([], True)
        assert bound(filtered) == (["the layer group filtering 'Tint'"], False)


def test_stroke_order_keeps_each_layers_settings_and_waits_for_a_fold(addon, tmp_path):
    """The figure lit, its layer parented to an Empty off the origin and filtered by view layer:
    with its arm folded over its eye, the render differs from the unordered one only where the
    arm covers the eye, and every layer Stroke Order draws keeps those settings and a blend mode
    (the layer rebuilt through curves lost them: a parented layer jumped, a lit one was drawn
    unlit). Unfolded, the drawing passes as it is, its keyframes included."""
    obj, tip = figure_seen_from_the_front()
    obj.use_grease_pencil_lights = True
    layer = obj.data.layers["Fills"]
    parent = bpy.data.objects.new("Layer Parent", None)
    bpy.context.scene.collection.objects.link(parent)
    parent.location = (0.1, 0.0, 0.05)
    layer.parent, layer.use_lights = parent, True
    layer.viewlayer_render = bpy.context.view_layer.name
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (np.pi / 2, 0.0, 0.0)  # shining along +Y, onto the drawing's front
    bpy.context.scene.collection.objects.link(sun)
    set_stroke_order(addon, obj, True)
    number_strokes(obj)
    bpy.context.view_layer.update()
    geometry = evaluated_geometry(obj)  # owns the drawings: keep it while reading
    frames = [f.frame_number for f in geometry.grease_pencil.layers["Fills"].frames]
    assert frames == [f.frame_number for f in layer.frames]  # unfolded: not rebuilt
    tip.location.x -= 2.0  # the arm over the body and its eye
    bpy.context.view_layer.update()
    body, arm, eye = range(3)
    assert list(drawn_order(obj, "Fills")) == [body, eye, arm]
    on, off = rendered_with_and_without_order(addon, obj, tmp_path)
    assert arm_blue(on) > arm_blue(off) + 10, (arm_blue(off), arm_blue(on))
    eye = off[..., :3].min(axis=2) > 0.8  # the eye, drawn over the arm, and its antialiased rim:
    eye |= np.roll(eye, 1, 0) | np.roll(eye, -1, 0) | np.roll(eye, 1, 1) | np.roll(eye, -1, 1)
    # Elsewhere the same picture but for a few antialiased pixels along the eye's rim (a lost
    # parent shifts the whole drawing 3 pixels; lost lighting recolours every pixel of it).
    changed = np.abs(on - off).max(axis=2) > 0.02
    assert (changed & ~eye).sum() < 0.01 * (off[..., :3].max(axis=2) > 0.02).sum(), (changed & ~eye).sum()
    set_stroke_order(addon, obj, True)
    layer.blend_mode = "MULTIPLY"
    bpy.context.view_layer.update()
    geometry = evaluated_geometry(obj)
    drawn = [part for part in geometry.grease_pencil.layers if part.name == "Fills"]
    assert len(drawn) > 1
    for part in drawn:
        assert (part.parent.name, part.use_lights, part.blend_mode, part.viewlayer_render) == (
            parent.name, True, "MULTIPLY", bpy.context.view_layer.name)


def stroke_order_input(addon, obj):
    """(modifier, identifier) of the rig's Stroke Order input."""
    modifier = addon.shapedeform_addon.rig_format.modifiers_of(obj)[0]
    return modifier, addon.shapedeform_addon.nodes.input_identifiers(modifier.node_group)["Stroke Order"]


def set_stroke_order(addon, obj, on):
    addon.shapedeform_addon.compat.set_modifier_input(*stroke_order_input(addon, obj), on)
    obj.update_tag()


def rendered_with_and_without_order(addon, obj, tmp_path):
    """Renders (100 x 100) of ``obj`` as it is, then with Stroke Order turned off."""
    on = renders.render(tmp_path / "on.png", size=100)
    set_stroke_order(addon, obj, False)
    return on, renders.render(tmp_path / "off.png", size=100)


def eye_white(pixels):
    return int((pixels[..., :3].min(axis=2) > 0.5).sum())


def arm_blue(pixels):
    """Pixels of the figure's blue arm over the white eye's square (rest place: the eye
    stays where it is, as the body is held)."""
    eye = eye_square(pixels)
    return int((eye[..., 2] > eye[..., 0] + 0.3).sum())


def eye_square(pixels):
    # The front camera spans x in [-1.3, 1.9] and z in [-1.6, 1.6]; the eye is x in [-0.7, -0.3],
    # z in [0.3, 0.7].
    size = pixels.shape[0]
    column = lambda x: int((x + 1.3) / 3.2 * size)
    row = lambda z: int((z + 1.6) / 3.2 * size)
    return pixels[row(0.3):row(0.7), column(-0.7):column(-0.3)]


def test_grease_pencil_stroke_order_keeps_materials_and_the_order_at_rest(addon, tmp_path):
    """Rendered: with Stroke Order on, a rig at rest draws exactly as with it off; posed, with the
    figure's arm folded over the eye drawn on its body, the arm covers the eye (off, the eye's
    white shows through the arm), in the drawing's own colours (Sort Elements alone dropped the
    material list, and every stroke drew in the default material)."""
    obj, tip = figure_seen_from_the_front()

    def picture(name, order):
        set_stroke_order(addon, obj, order)
        return renders.render(tmp_path / f"{name}.png", size=100)

    np.testing.assert_allclose(picture("rest_on", True), picture("rest_off", False), atol=1e-3)
    tip.location.x -= 2.0
    bpy.context.view_layer.update()
    off, on = picture("posed_off", False), picture("posed_on", True)
    drawn = on[..., :3].max(axis=2) > 0.02
    red = on[..., 0] > on[..., 2] + 0.3
    assert red.sum() > 0.5 * drawn.sum(), (red.sum(), drawn.sum())  # the body keeps its material
    assert arm_blue(on) > arm_blue(off) + 10, (arm_blue(off), arm_blue(on))
    assert eye_white(on) < 0.7 * eye_white(off), (eye_white(off), eye_white(on))


def test_a_baked_grease_pencil_keeps_its_stroke_order_with_the_extension_disabled(addon, tmp_path):
    """The bake is the cage's motion; the modifier, saved in the file, still sorts the strokes."""
    obj, tip = figure_seen_from_the_front()
    tip.keyframe_insert("location", frame=1)
    tip.location.x -= 2.0  # the arm over the eye
    tip.keyframe_insert("location", frame=10)
    assert addon.shapedeform_addon.bake.bake_objects([obj], 1, 10) == [obj]
    scene = bpy.context.scene
    scene.frame_set(10)
    live = renders.render(tmp_path / "live.png", size=100)
    set_stroke_order(addon, obj, False)
    unordered = renders.render(tmp_path / "unordered.png", size=100)
    set_stroke_order(addon, obj, True)
    addon_utils.disable(ADDON_MODULE, default_set=True)
    try:
        scene.frame_set(9)
        scene.frame_set(10)
        alone = renders.render(tmp_path / "alone.png", size=100)
        assert np.abs(alone - live).max() < 1e-6  # the same picture
        assert eye_white(alone) < 0.7 * eye_white(unordered), (eye_white(unordered), eye_white(alone))
    finally:
        addon_utils.enable(ADDON_MODULE, default_set=True)


def test_a_baked_overlap_renders_the_same_with_the_extension_disabled(addon, tmp_path):
    obj, arm = figure()
    swing_arm_across(obj)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.add_handle(location=(0.0, -0.5, 0.0), kind="OVERLAP") == {"FINISHED"}
    pin = obj.shapedeform.handles[-1].object  # on the torso, reaching the lower half of it
    pin.shapedeform.extent = 0.3
    pin.keyframe_insert('shapedeform.in_front', frame=1)
    assert addon.shapedeform_addon.bake.bake_objects([obj], 1, 10) == [obj]
    camera = renders.camera_over((0.4, 0.0), 2.6)
    bpy.context.scene.frame_set(10)
    live = renders.render(tmp_path / "baked_live.png", size=SIZE)
    addon_utils.disable(ADDON_MODULE, default_set=True)
    try:
        bpy.context.scene.frame_set(9)
        bpy.context.scene.frame_set(10)
        alone = renders.render(tmp_path / "baked_alone.png", size=SIZE)
        assert part_shares(obj, arm, camera, alone)[0] >= 0.97
        assert np.abs(alone - live).max() < 1e-6  # the same picture
    finally:
        addon_utils.enable(ADDON_MODULE, default_set=True)



def figure_picture(folder):
    """A picture with alpha of a blue torso and a red arm reaching right from its top, imported
    as a plane lying in XY (``+Z``); returns the object, a function giving a pixel's place on
    the plane, and the x of the shoulder (where the arm meets the torso)."""
    w, h = 96, 96
    pixels = np.zeros((h, w, 4), np.float32)
    torso, arm = (slice(4, 92), slice(20, 44)), (slice(64, 76), slice(44, 90))
    pixels[torso] = TORSO
    pixels[arm] = ARM
    obj = checks.import_picture(folder, "figure", pixels, align_axis="+Z", shader="SHADELESS")
    corners = checks.mesh_points(obj)
    low, high = corners.min(axis=0)[:2], corners.max(axis=0)[:2]

    def at(col, row):  # a pixel's place on the plane (rows count from the bottom)
        return tuple(low + (np.array([col, row]) / [w, h]) * (high - low)) + (0.0,)
    return obj, at, low[0] + 44 / w * (high - low)[0]


def test_an_image_plane_folded_over_itself_renders_one_layer_in_front(addon, tmp_path):
    obj, at, shoulder_x = figure_picture(tmp_path)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, at(32, 10))
    checks.add_handle(obj, at(32, 50))
    tip = checks.add_handle(obj, at(86, 70))
    tip.location = at(2, 60)
    tip.rotation_euler.z = 3.0
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    # The cut-out's faces: the arm's are those right of the shoulder at rest.
    centres = np.array([p.center.x for p in obj.data.polygons])
    arm = centres > shoulder_x + 0.02
    middle = np.array(at(48, 48)[:2])
    camera = renders.camera_over(middle, 1.3)
    pixels = renders.render(tmp_path / "image_plane.png", size=SIZE, color_type="TEXTURE")
    # A cut-out reaches about a texel past the picture's edge (transparent texels): judge the
    # overlap inside that, where both layers show their picture.
    texel = (np.array(at(1, 1)) - np.array(at(0, 0)))[0]
    arm_share, torso_share = part_shares(obj, arm, camera, pixels, margin=3 * texel)
    assert arm_share >= 0.97, f"arm {arm_share:.3f}, torso {torso_share:.3f}"


def test_a_pin_moved_by_hand_binds_to_the_point_it_is_left_on(addon):
    """As After Effects moves a pin: an overlap pin on the torso, moved with its Empty onto the
    hand where the hand lies over the torso, rides on the hand from then on and sends the hand
    behind; the pose does not move. It used to stay bound to the torso's point, its Empty
    floating off the shape by what it was moved."""
    rig_format = addon.shapedeform_addon.rig_format
    obj, arm, rest, posed = swung_figure()
    hand = forearm_over_torso(rest, posed)
    assert len(hand) >= 2, "the hand does not lie over the torso"
    torso = np.flatnonzero(rest[:, 0] < 0.25)
    checks.select_only(obj)
    on_torso = posed[torso[np.argmin(np.linalg.norm(posed[torso, :2] - [0.0, -0.5], axis=1))]]
    assert bpy.ops.shapedeform.add_handle(location=tuple(on_torso), kind="OVERLAP") == {"FINISHED"}
    item = obj.shapedeform.handles[-1]
    pin = item.object
    pin.shapedeform.in_front = -1.0
    bpy.context.view_layer.update()
    assert rest[item[rig_format.PIN_POINT], 0] < 0.25  # on the torso
    hand_heights = checks.evaluated_mesh_points(obj)[hand, 2]

    target = posed[hand[0]]
    # As G moves it: its location takes the move (the figure is not turned, scaled or moved).
    pin.location = tuple(target - np.array(pin.matrix_world.translation))
    bpy.context.view_layer.update()

    point = item[rig_format.PIN_POINT]
    assert rest[point, 0] > 0.8, f"the pin stayed on rest point {rest[point]}"
    assert tuple(pin.parent_vertices)[0] == point and tuple(pin.location) == (0.0, 0.0, 0.0)
    shown = checks.evaluated_mesh_points(obj)
    np.testing.assert_allclose(np.array(pin.matrix_world.translation)[:2], shown[point, :2], atol=1e-5)
    np.testing.assert_allclose(np.array(pin.matrix_world.translation)[:2], target[:2], atol=0.08)
    np.testing.assert_allclose(shown[:, :2], posed[:, :2], atol=1e-6)  # a pin pulls nothing
    below = shown[hand, 2] - hand_heights
    assert np.all(below < -0.005), f"the hand did not go behind: its heights changed by {below}"
    # A location keyed (or driven) is the animator's to set: the pin stays bound where it is.
    pin.location = (0.1, 0.0, 0.0)
    pin.keyframe_insert("location", frame=10)
    bpy.context.scene.frame_set(10)
    assert item[rig_format.PIN_POINT] == point and tuple(pin.location) == pytest.approx((0.1, 0.0, 0.0))


def pinned_figure(location=(0.0, -0.5, 0.0)):
    """The figure posed with its arm across the torso (frame 10) and an overlap pin added at
    ``location``: (object, the pin's handle item, its Empty)."""
    obj = swung_figure()[0]
    checks.select_only(obj)
    assert bpy.ops.shapedeform.add_handle(location=location, kind="OVERLAP") == {"FINISHED"}
    item = obj.shapedeform.handles[-1]
    bpy.context.view_layer.update()
    return obj, item, item.object


@pytest.mark.parametrize("how", ["keyed", "driven"])
def test_a_pin_whose_location_is_animated_on_one_axis_stays_on_its_point(addon, how):
    """Only location Y keyed (or driven): the pin is the animator's to move, on its point. Only
    X was looked at, so the pin was bound anew and its key then moved it 0.1 off its new point."""
    point_key = addon.shapedeform_addon.rig_format.PIN_POINT
    obj, item, pin = pinned_figure()
    point = item[point_key]
    if how == "keyed":
        pin.location.y = 0.1
        pin.keyframe_insert("location", index=1, frame=10)
    else:
        pin.driver_add("location", 1).driver.expression = "0.1"
    bpy.context.view_layer.update()
    bpy.context.scene.frame_set(3)
    assert item[point_key] == point and pin.location.y == pytest.approx(0.1)


def test_a_pin_left_off_the_shape_rides_on_its_nearest_point(addon):
    """Left beside the swung hand, off the shape: on the shape's nearest point. It went on the
    rest point under the place mapped back through the nearest triangle, 1.03 away."""
    point_key = addon.shapedeform_addon.rig_format.PIN_POINT
    for target in ((-0.6, 0.0, 0.0), (0.5, 0.5, 0.0), (-1.3, -0.2, 0.0)):
        obj, item, pin = pinned_figure()
        pin.location = tuple(np.array(target) - np.array(pin.matrix_world.translation))
        bpy.context.view_layer.update()
        shown = checks.evaluated_mesh_points(obj)
        cage = addon.shapedeform_addon.rig_format.shown_pose(obj.shapedeform.cage)
        distances = np.linalg.norm(cage[:, :2] - target[:2], axis=1)
        assert distances[item[point_key]] == pytest.approx(distances.min(), abs=1e-6), target
        assert np.isfinite(shown).all()


def test_a_location_field_dragged_moves_a_pin_by_what_it_says(addon, monkeypatch):
    """A Location field dragged in the sidebar writes its start value plus the drag at each
    step, with no transform running: re-seated at each step, the pin moved 0.6 for a drag of
    0.3. With a window, the pin is re-seated once the updates pause (the timer's call here)."""
    handlers = addon.shapedeform_addon.handlers
    point_key = addon.shapedeform_addon.rig_format.PIN_POINT
    monkeypatch.setattr(handlers, "_windowless", lambda: False)
    obj, item, pin = pinned_figure()
    start, point = np.array(pin.matrix_world.translation), item[point_key]
    for y in (0.1, 0.2, 0.3):
        pin.location = (0.0, y, 0.0)
        bpy.context.view_layer.update()
        assert item[point_key] == point  # not while the field is dragged
    assert bpy.app.timers.is_registered(handlers._reseat_dropped_pins)
    bpy.app.timers.unregister(handlers._reseat_dropped_pins)
    handlers._reseat_dropped_pins()  # the updates paused
    bpy.context.view_layer.update()
    moved = np.array(pin.matrix_world.translation) - start
    assert tuple(pin.location) == (0.0, 0.0, 0.0) and item[point_key] != point
    assert moved[1] == pytest.approx(0.3, abs=0.06) and abs(moved[0]) < 0.06


def test_a_file_with_a_pin_an_older_version_left_off_its_point_keeps_the_pin_on_it(addon, tmp_path):
    """An older version let a pin's Empty be moved off its point (it moved nothing): opened now,
    the pin goes back on its point, and moving the owner alone does not bind it anew (it went
    from point 38 to 83 with the first update that moved it)."""
    point_key = addon.shapedeform_addon.rig_format.PIN_POINT
    obj, item, pin = pinned_figure()
    point = item[point_key]
    path, name = str(tmp_path / "older.blend"), obj.name
    addon_utils.disable(ADDON_MODULE, default_set=True)  # nothing of this version sees the move
    try:
        pin.location = (0.4, 0.3, 0.0)
        bpy.context.view_layer.update()
        bpy.ops.wm.save_as_mainfile(filepath=path)
    finally:
        addon_utils.enable(ADDON_MODULE, default_set=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects[name]
    item = next(i for i in obj.shapedeform.handles if i.object.shapedeform.pin_kind == "OVERLAP")
    assert tuple(item.object.location) == (0.0, 0.0, 0.0)
    obj.location.x += 0.5
    bpy.context.view_layer.update()
    assert item[point_key] == point


def test_a_pose_that_does_not_overlap_itself_stays_in_its_plane_under_a_card_in_front(addon, tmp_path):
    """A body bent without folding over itself, and a card set 1 cm in front of it where the
    body's end lands (a cut-out puppet of several objects layered a little apart): the rig lifted
    everything that moved, up to 1.5 cm, through the card, which kept a quarter of its pixels
    red (QA). Only where the pose overlaps itself is there an order to give: the body stays in its
    plane and the card renders whole."""
    import bmesh

    mesh = bpy.data.meshes.new("Body")
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=16, y_segments=4, size=0.5)
    bmesh.ops.scale(bm, vec=(4.0, 1.0, 1.0), verts=bm.verts)
    bm.to_mesh(mesh)
    bm.free()
    mesh.materials.append(renders.flat_material("Body", TORSO))
    body = bpy.data.objects.new("Body", mesh)
    bpy.context.scene.collection.objects.link(body)
    checks.select_only(body)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(body, (-2.0, 0.0, 0.0))
    end = checks.add_handle(body, (2.0, 0.0, 0.0))
    end.location.y += 1.2
    end.location.x -= 0.6
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(body)
    top = posed[np.argmax(posed[:, 1])]
    card = bpy.data.objects.new("Card", bpy.data.meshes.new("Card"))
    card.data.from_pydata([(-0.15, -0.15, 0), (0.15, -0.15, 0), (0.15, 0.15, 0), (-0.15, 0.15, 0)], [], [(0, 1, 2, 3)])
    card.data.materials.append(renders.flat_material("Card", ARM))
    card.location = (top[0], top[1], 0.01)
    bpy.context.scene.collection.objects.link(card)
    camera = renders.camera_over((0.5, 0.5), 5.0)
    pixels = renders.render(tmp_path / "card.png", size=100)
    centres = renders.pixel_centres(camera, 100)
    under = (np.abs(centres[..., 0] - card.location.x) < 0.1) & (np.abs(centres[..., 1] - card.location.y) < 0.1)
    card_share, body_share = shares(pixels[under])
    assert card_share > 0.97, f"the card shows {card_share:.2f}, the body {body_share:.2f}"
    np.testing.assert_array_equal(posed[:, 2], 0.0)  # nothing overlaps: no lift
