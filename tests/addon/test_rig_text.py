# SPDX-License-Identifier: GPL-3.0-or-later
"""Rigging text objects as they are: the text stays editable, its glyphs' outlines are the shape."""

import bpy
import numpy as np
import pytest
import shapely

import rig_checks as checks


def text(body="Ba"):
    bpy.ops.object.text_add()
    obj = bpy.context.active_object
    obj.data.body = body
    return obj


def text_state(obj):
    data = obj.data
    return data.body, data.size, data.space_character, data.font.name, len(obj.modifiers)


def test_a_text_object_is_posed_as_text_and_unbinds_to_itself(addon, tmp_path):
    """Bound without converting: the glyphs' outlines make the shape, the modifier poses what the
    text shows (handles reached, no cage triangle flipped, in its plane), the text stays text, and
    Unbind leaves it as it was."""
    obj = text("Ba")
    obj.name = "Title"
    before = text_state(obj)
    rest = checks.evaluated_vertices(obj)
    size = float(np.linalg.norm(np.ptp(rest, axis=0)))
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    at_left = rest[np.argmin(np.linalg.norm(rest - [lo[0], lo[1], 0], axis=1))]
    grip = np.argmin(np.linalg.norm(rest - [hi[0], hi[1], 0], axis=1))
    checks.bind_with_handles(obj, at_left, rest[grip])
    right = obj.shapedeform.handles[1].object
    assert obj.type == "FONT" and obj.shapedeform.kind == "TEXT"
    checks.refine(addon.shapedeform_addon, obj, 0)  # the fill's own points, to follow them one by one
    np.testing.assert_allclose(checks.evaluated_vertices(obj), rest, atol=1e-4)
    right.location.y += 0.3
    bpy.context.view_layer.update()
    posed = checks.evaluated_vertices(obj)
    assert obj.shapedeform.status == ""
    assert np.all(np.isfinite(posed)) and np.abs(posed - rest).max() > 0.2
    checks.assert_in_front_only(rest, posed, (0, 0, 1.0), size)
    np.testing.assert_allclose(posed[grip, :2], np.array(right.matrix_world.translation)[:2], atol=1e-3 * size)
    cage = checks.cage(obj)
    tris = checks.triangles(cage)
    cage_rest = checks.mesh_points(cage)
    cage_posed = checks.evaluated_vertices(cage)
    assert np.all(np.sign(checks.signed_areas(cage_rest[:, :2], tris))
                  == np.sign(checks.signed_areas(cage_posed[:, :2], tris)))
    assert text_state(obj)[:4] == before[:4]

    path = str(tmp_path / "title.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Title"]
    np.testing.assert_allclose(checks.evaluated_vertices(obj), posed, atol=1e-5)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert text_state(obj) == before
    np.testing.assert_array_equal(checks.evaluated_vertices(obj), rest)
    assert [o.name for o in bpy.data.objects] == ["Title"]


def test_a_letters_hole_stays_a_hole(addon):
    """An 'o' bound as text: the cage has a hole where the letter has one."""
    obj = text("o")
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    cage = checks.cage(obj)
    points = checks.mesh_points(cage)[:, :2]
    tris = checks.triangles(cage)
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    corners = points[tris]
    # Barycentric test of the letter's centre against every cage triangle.
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    def cross(u, v):
        return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    d1, d2, d3 = cross(b - a, centre - a), cross(c - b, centre - b), cross(a - c, centre - c)
    inside = ((d1 >= 0) & (d2 >= 0) & (d3 >= 0)) | ((d1 <= 0) & (d2 <= 0) & (d3 <= 0))
    assert not inside.any()


def test_text_typed_after_binding_follows_the_pose(addon):
    """Typing on a posed text keeps it posed: the new letters are mapped by the part they lie
    next to (no NaN, the old letters where they were); Bind again rigs them as letters."""
    obj = text("Hat")
    rest_t = checks.evaluated_vertices(obj)
    obj.data.body = "Ha"
    rest = checks.evaluated_vertices(obj)
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    middle = 0.5 * (lo[1] + hi[1])
    _, right = checks.bind_with_handles(obj, [lo[0] + 0.02, middle, 0], [hi[0] - 0.02, middle, 0])
    checks.refine(addon.shapedeform_addon, obj, 0)  # the fill's own points, to compare them one by one
    right.location.y += 0.2
    bpy.context.view_layer.update()
    posed = checks.evaluated_vertices(obj)
    obj.data.body = "Hat"
    bpy.context.view_layer.update()
    longer = checks.evaluated_vertices(obj)
    assert np.all(np.isfinite(longer)) and len(longer) > len(posed)
    assert obj.shapedeform.status == ""
    # The letters already there did not move (the fill may triangulate them anew: compare as sets).
    nearest = np.linalg.norm(longer[:, None, :2] - posed[None, :, :2], axis=2).min(axis=0)
    assert nearest.max() < 1e-4
    new, new_rest = (points[points[:, 0] > hi[0] + 0.05, 1] for points in (longer, rest_t))
    assert len(new) and len(new_rest)
    assert new.min() > new_rest.min() + 0.1 and new.max() > new_rest.max() + 0.1  # carried up with the right side


def test_a_letter_bends_with_its_rig(addon):
    """Bfont's I is one quad from foot to head: mapped at its four corners it would stay a
    straight bar while the rig bends it (0.14 off at mid height, 5% of its size). Bind refines
    the text's fill to the cage's spacing, so its edge follows the bent cage."""
    obj = text("I")
    obj.data.size = 4.0
    rest = checks.evaluated_vertices(obj)
    assert len(rest) == 4
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    middle_x, middle_y = 0.5 * (lo[:2] + hi[:2])
    _, top = checks.bind_with_handles(obj, [middle_x, lo[1] + 0.1, 0], [middle_x, hi[1] - 0.1, 0])
    top.location.x += 1.5
    bpy.context.view_layer.update()
    shapedeform = addon.shapedeform_addon
    assert checks.refine(shapedeform, obj) > 0

    def shown_area():
        evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        mesh.calc_loop_triangles()
        tris = np.array([t.vertices[:] for t in mesh.loop_triangles])
        points = np.array([v.co for v in mesh.vertices])[:, :2]
        evaluated.to_mesh_clear()
        return shapely.union_all(shapely.polygons(points[tris]))

    shown = shown_area()
    checks.refine(shapedeform, obj, 6)  # the cage's own map, as finely as the modifier maps
    bent = shown_area()
    assert shown.symmetric_difference(bent).area < 0.01 * bent.area


def test_a_line_of_text_is_refined_within_its_budget(addon):
    """Two words (449 fill faces): their fill is cut too (it was left whole, as the cut was
    capped by the cage's triangle count), but no finer than the budget that keeps it live, also
    when more is typed after Bind chose the cut."""
    obj = text("Hello world")
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert checks.refine(addon.shapedeform_addon, obj) >= 2
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    faces = len(evaluated.to_mesh().polygons)
    evaluated.to_mesh_clear()
    assert faces <= 50_000
    # Typed longer afterwards (the Refine chosen for two words would cut a sentence's fill
    # into 318,000 faces, a third of a second per update): still within the budget.
    obj.data.body = "Hello world, how are you doing today?"
    bpy.context.view_layer.update()
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    faces = len(evaluated.to_mesh().polygons)
    evaluated.to_mesh_clear()
    assert 12_500 < faces <= 50_000


def test_add_handle_in_text_edit_mode_says_how(addon):
    obj = text("Hi")
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="EDIT")
    with pytest.raises(RuntimeError, match="is text, which has no points to select: add handles in Object Mode"):
        bpy.ops.shapedeform.add_handle()
    assert obj.mode == "EDIT" and len(obj.shapedeform.handles) == 0


def test_a_text_converted_to_a_curve_is_rigged_as_a_curve(addon):
    """Convert > Curve keeps the rig working on the curve it makes, whose control points Edit
    Mode can select for handles (the rig still took it for a text, which has none)."""
    obj = text("Hi")
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.select_only(obj)
    assert bpy.ops.object.convert(target="CURVE") == {"FINISHED"}
    obj = bpy.context.active_object
    assert obj.type == "CURVE" and obj.shapedeform.is_bound
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.curve.select_all(action="DESELECT")
    obj.data.splines[0].bezier_points[0].select_control_point = True
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    assert len(obj.shapedeform.handles) == 1


def test_a_text_of_spaces_is_refused_with_a_reason(addon):
    obj = text("   ")
    with pytest.raises(RuntimeError, match="shows no glyphs"):
        bpy.ops.shapedeform.bind()
    assert not obj.shapedeform.is_bound and not obj.modifiers and len(bpy.data.objects) == 1
