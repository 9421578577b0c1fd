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
