# SPDX-License-Identifier: GPL-3.0-or-later
"""Rigging Blender's own grease-pencil monkey (GPv3, drawn in the XZ plane)."""

import bpy
import numpy as np
import pytest

import rig_checks as checks


def drawing_points(obj, evaluated=True):
    data = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data if evaluated else obj.data
    result = []
    for layer in data.layers:
        attribute = layer.current_frame().drawing.attributes["position"]
        flat = np.empty(len(attribute.data) * 3, np.float32)
        attribute.data.foreach_get("vector", flat)
        result.append(flat.reshape(-1, 3))
    return np.concatenate(result)


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
    assert np.abs(posed[:, 1]).max() < 1e-6          # still in the XZ plane
    tip = np.argmin(np.linalg.norm(rest - top, axis=1))
    assert posed[tip, 0] == pytest.approx(top[0] + 0.3, abs=0.02)
    assert posed[tip, 2] == pytest.approx(top[2], abs=0.02)
    assert np.abs(posed - rest).max() == pytest.approx(0.3, abs=0.05)

    path = str(tmp_path / "monkey.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Monkey"]
    np.testing.assert_array_equal(drawing_points(obj, evaluated=False), posed)
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
    assert obj.shapedeform["gp_layers"] == "Lines"
    obj.shapedeform.is_bound and bpy.ops.shapedeform.unbind()
    obj.shapedeform.layers = "Nope"
    with pytest.raises(RuntimeError, match="no layer 'Nope'"):
        bpy.ops.shapedeform.bind()
