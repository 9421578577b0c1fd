# SPDX-License-Identifier: GPL-3.0-or-later
"""The compatibility module on the running Blender: both ways to a channelbag work."""

import bpy
import pytest
from bpy_extras import anim_utils


def _action_with_slot():
    action = bpy.data.actions.new("compat")
    return action, action.slots.new(id_type="OBJECT", name="owner")


@pytest.mark.parametrize("with_helper", [True, False], ids=["as-found", "without-5.0-helper"])
def test_ensure_channelbag_makes_one_bag_that_keys(addon, monkeypatch, with_helper):
    compat = addon.shapedeform_addon.compat
    if not with_helper:  # the path Blender 4.5 takes, exercised on every version
        monkeypatch.delattr(anim_utils, "action_ensure_channelbag_for_slot", raising=False)
    action, slot = _action_with_slot()
    assert compat.channelbag(action, slot) is None
    bag = compat.ensure_channelbag(action, slot)
    curve = bag.fcurves.new("location", index=2)
    curve.keyframe_points.insert(1, 3.0)
    again = compat.ensure_channelbag(action, slot)
    assert [c.data_path for c in again.fcurves] == ["location"]
    assert compat.channelbag(action, slot).fcurves[0].evaluate(1) == pytest.approx(3.0)

    owner = bpy.data.objects.new("owner", None)
    owner.animation_data_create().action = action
    owner.animation_data.action_slot = slot
    bpy.context.scene.collection.objects.link(owner)
    bpy.context.scene.frame_set(1)
    assert owner.location.z == pytest.approx(3.0)


def test_modifier_inputs_are_set_and_read_back_and_reach_the_nodes(addon):
    """Whichever way this Blender keeps a Geometry Nodes modifier's inputs."""
    import numpy as np

    shapedeform = addon.shapedeform_addon
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    cage = bpy.context.active_object
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.quads_convert_to_tris()
    bpy.ops.object.mode_set(mode="OBJECT")
    rest = np.array([v.co for v in cage.data.vertices], dtype=np.float32)
    cage.data.attributes.new("sd_rest", "FLOAT_VECTOR", "POINT").data.foreach_set("vector", rest.ravel())
    cage.data.attributes["position"].data.foreach_set("vector", (rest + [0.0, 0.5, 0.0]).astype(np.float32).ravel())
    bpy.ops.mesh.primitive_plane_add(size=1.0)
    obj = bpy.context.active_object
    group = shapedeform.nodes.node_group()
    modifier = obj.modifiers.new("Shape Deform", "NODES")
    modifier.node_group = group
    ids = shapedeform.nodes.input_identifiers(group)
    assert shapedeform.compat.modifier_input(modifier, ids["Cage"]) is None
    shapedeform.compat.set_modifier_input(modifier, ids["Cage"], cage)
    assert shapedeform.compat.modifier_input(modifier, ids["Cage"]) == cage
    # What the sidebar draws with layout.prop resolves to the same input.
    struct, prop = shapedeform.compat.modifier_input_property(modifier, ids["Refine"])
    shapedeform.compat.set_modifier_input(modifier, ids["Refine"], 2)
    assert struct.path_resolve(prop) == 2
    shapedeform.compat.set_modifier_input(modifier, ids["Refine"], 0)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    moved = np.array([v.co for v in obj.evaluated_get(depsgraph).data.vertices])
    own = np.array([v.co for v in obj.data.vertices])
    np.testing.assert_allclose(moved, own + [0.0, 0.5, 0.0], atol=1e-6)  # the cage's shift, carried over
