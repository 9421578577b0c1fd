# SPDX-License-Identifier: GPL-3.0-or-later
"""Rigging text objects as they are: the text stays editable, its glyphs' outlines are the shape."""

import bpy
import numpy as np
import pytest

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
    new, new_rest = (points[points[:, 0] > hi[0] + 0.05] for points in (longer, rest_t))
    assert len(new) == len(new_rest) > 0
    assert new[:, 1].mean() > new_rest[:, 1].mean() + 0.1  # carried up with the right side


def test_add_handle_in_text_edit_mode_says_how(addon):
    obj = text("Hi")
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="EDIT")
    with pytest.raises(RuntimeError, match="is text, which has no points to select: add handles in Object Mode"):
        bpy.ops.shapedeform.add_handle()
    assert obj.mode == "EDIT" and len(obj.shapedeform.handles) == 0


def test_a_text_of_spaces_is_refused_with_a_reason(addon):
    obj = text("   ")
    with pytest.raises(RuntimeError, match="shows no glyphs"):
        bpy.ops.shapedeform.bind()
    assert not obj.shapedeform.is_bound and not obj.modifiers and len(bpy.data.objects) == 1
