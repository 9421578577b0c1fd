# SPDX-License-Identifier: GPL-3.0-or-later
"""A failed update keeps the last good pose, says why, and never writes NaN."""

import math

import bpy
import numpy as np

import rig_checks as checks
from test_rig_mesh import rig_with_two_handles


def test_a_handle_moved_to_nan_keeps_the_last_pose_and_reports(addon):
    obj, _, handle = rig_with_two_handles()
    handle.location.y += 0.4
    bpy.context.view_layer.update()
    good = checks.evaluated_mesh_points(obj)
    assert obj.shapedeform.status == ""

    handle.location.x = math.nan  # a driver or script gone wrong
    bpy.context.view_layer.update()
    after = checks.evaluated_mesh_points(obj)
    assert np.all(np.isfinite(after))
    np.testing.assert_array_equal(after, good)
    assert "non-finite" in obj.shapedeform.status

    handle.location.x = 1.0  # fixed: the rig poses again and the message goes
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    assert np.all(np.isfinite(checks.evaluated_mesh_points(obj)))
