# SPDX-License-Identifier: GPL-3.0-or-later
"""Rig settings reach the solver: Prevent Folds."""

import bpy

import rig_checks as checks
from test_rig_mesh import grid


def test_prevent_folds_reaches_the_deformer_and_reposes(addon):
    rig = addon.shapedeform_addon.rig
    obj = grid()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    assert rig.get(obj).deformer.prevent_flips is True  # on by default
    obj.shapedeform.prevent_flips = False
    bpy.context.view_layer.update()
    assert rig.get(obj).deformer.prevent_flips is False
