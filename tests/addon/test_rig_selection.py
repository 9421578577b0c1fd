# SPDX-License-Identifier: GPL-3.0-or-later
"""Adding handles at the selected points of curves and grease-pencil drawings."""

import bpy
import numpy as np
import pytest

import rig_checks as checks
from test_rig_curve import text_curve


def handle_locations(obj):
    return np.array([item.object.matrix_world.translation for item in obj.shapedeform.handles])


def test_add_handles_at_selected_curve_points(addon):
    obj = text_curve("B")
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    points = obj.data.splines[0].bezier_points
    for point in points:
        point.select_control_point = point.select_left_handle = point.select_right_handle = False
    chosen = (0, 3)
    for i in chosen:
        points[i].select_control_point = True
    expected = [checks.world(obj, points[i].co) for i in chosen]  # Edit Mode rebuilds the splines
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    np.testing.assert_allclose(sorted(map(tuple, handle_locations(obj))), sorted(expected), atol=1e-5)


def test_add_handles_at_selected_grease_pencil_points(addon):
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    expected = []
    for layer in obj.data.layers:
        drawing = layer.current_frame().drawing
        count = len(drawing.attributes["position"].data)
        selection = drawing.attributes.get(".selection") or drawing.attributes.new(".selection", "BOOLEAN", "POINT")
        mask = np.zeros(count, dtype=bool)
        if layer.name == "Lines":
            mask[[0, count // 2]] = True
            positions = np.empty(count * 3, np.float32)
            drawing.attributes["position"].data.foreach_get("vector", positions)
            expected += [checks.world(obj, p) for p in positions.reshape(-1, 3)[mask]]
        selection.data.foreach_set("value", mask)
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    assert len(obj.shapedeform.handles) == 2
    np.testing.assert_allclose(sorted(map(tuple, handle_locations(obj))), sorted(expected), atol=1e-5)


def test_grease_pencil_selection_as_blender_keeps_it(addon):
    """Blender drops ``.selection`` when all is selected and keeps it per stroke in Stroke
    select mode: both are read (Add Handle said nothing was selected); a hidden layer's points
    are not Edit Mode's to select."""
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    obj = bpy.context.active_object
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    selected = addon.shapedeform_addon.sources.grease_pencil.selected
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.grease_pencil.select_all(action="SELECT")
    total = sum(len(layer.current_frame().drawing.attributes["position"].data) for layer in obj.data.layers)
    assert len(selected(obj)) == total
    lines = len(obj.data.layers["Lines"].current_frame().drawing.attributes["position"].data)
    obj.data.layers["Fills"].hide = True
    assert len(selected(obj)) == lines
    obj.data.layers["Fills"].hide = False
    group = obj.data.layer_groups.new("Group")  # a hidden group hides its layers from Edit Mode
    obj.data.layers.move_to_layer_group(obj.data.layers["Fills"], group)
    group.hide = True
    assert len(selected(obj)) == lines
    group.hide = False
    # So do hidden materials (Deselect All leaves their strokes' selection as it was).
    black = next(slot.material for slot in obj.material_slots if slot.material.name == "Black")
    black.grease_pencil.hide = True
    shown = sum(len(stroke.points) for layer in obj.data.layers for stroke in layer.current_frame().drawing.strokes
                if obj.material_slots[stroke.material_index].material != black)
    assert 0 < len(selected(obj)) == shown < total
    black.grease_pencil.hide = False

    bpy.ops.grease_pencil.select_all(action="DESELECT")
    drawing = obj.data.layers["Lines"].current_frame().drawing
    for layer in obj.data.layers:  # Stroke select mode: one stroke of Lines selected
        other = layer.current_frame().drawing
        other.attributes.remove(other.attributes[".selection"])
        marks = other.attributes.new(".selection", "BOOLEAN", "CURVE")
        if layer.name == "Lines":
            marks.data[1].value = True
    stroke = drawing.strokes[1]
    expected = np.array([p.position for p in stroke.points])
    np.testing.assert_allclose(selected(obj), expected, atol=1e-6)
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    assert len(obj.shapedeform.handles) >= 1


def test_in_object_mode_a_handle_goes_to_the_3d_cursor(addon):
    from test_rig_mesh import grid

    obj = grid()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    bpy.context.scene.cursor.location = (0.8, -1.1, 0.7)  # above the shape: projected onto it
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    location = handle_locations(obj)[0]
    np.testing.assert_allclose(location[:2], (0.8, -1.1), atol=1e-6)
    assert abs(location[2] - obj.matrix_world.translation.z) < 1e-6


def test_more_selected_points_than_handles_fit_says_how_many_fit(addon):
    """Every vertex of a grid selected in Edit Mode: Add Handle refused with "every point of
    the shape already belongs to a handle", which did not say why (each handle holds a few
    points, so 91 do not fit on 91 points) nor what to do. Nothing is added either way."""
    from test_rig_mesh import grid

    obj = grid()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    with pytest.raises(RuntimeError, match=r"of the 91 handles asked for fit .* select fewer points"):
        bpy.ops.shapedeform.add_handle()
    bpy.ops.object.mode_set(mode="OBJECT")
    assert len(obj.shapedeform.handles) == 0


def test_a_refused_multi_add_gives_the_handle_list_back(addon):
    """Refused, the handles added before the one that did not fit are taken back, and only
    they: the entry of a handle deleted for good stays listed (as deleted) until the user
    removes it, and the list's active item stays (both went)."""
    from test_rig_mesh import grid

    obj = grid()
    left, right, gone = checks.bind_with_handles(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    bpy.data.objects.remove(gone)  # deleted for good: its entry names no Empty
    obj.shapedeform["active_handle"] = 0
    checks.select_only(obj)
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    with pytest.raises(RuntimeError, match="select fewer points"):
        bpy.ops.shapedeform.add_handle()
    bpy.ops.object.mode_set(mode="OBJECT")
    assert [item.object for item in obj.shapedeform.handles] == [left, right, None]
    assert obj.shapedeform.active_handle == 0


def test_a_handle_that_does_not_fit_says_what_to_change(addon):
    """Handles until every point of the shape is taken: the next one is refused with what
    gives room (it only said every point already belonged to a handle)."""
    from test_rig_mesh import grid

    obj = grid()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    bpy.context.view_layer.objects.active = obj
    with pytest.raises(RuntimeError, match="lower Handle Region, or bind again with a higher Graph Density"):
        for _ in range(100):
            bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.0, 0.0, 0.0]))

