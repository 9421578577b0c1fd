# SPDX-License-Identifier: GPL-3.0-or-later
"""What stays on screen is what renders: a Viewport-budget pose that stopped short of converging
is solved again with the Render budget once updates pause, on seeded random drags."""

import bpy
import numpy as np
import pytest
from mathutils import Matrix

import rig_checks as checks


def ring_character():
    """A bar with a hole and a side arm: a shape with a limb to swing and a hole to keep."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=20, y_subdivisions=10, size=1.0)
    obj = bpy.context.active_object
    obj.data.transform(Matrix.Diagonal((3.0, 1.0, 1.0, 1.0)))
    bpy.context.view_layer.update()
    return obj


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_pose_that_stopped_short_is_refined_to_the_render_pose(addon, seed):
    rig = addon.shapedeform_addon.rig
    handlers = addon.shapedeform_addon.handlers
    rng = np.random.default_rng(seed)
    obj = ring_character()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    rest = checks.mesh_points(obj)
    size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    ends = [rest[np.argmin(rest[:, 0])], rest[np.argmax(rest[:, 0])]]
    pinned = checks.add_handle(obj, checks.world(obj, ends[0]))
    dragged = checks.add_handle(obj, checks.world(obj, ends[1]))
    assert pinned is not None
    angle = rng.uniform(-1.0, 1.0)
    shift = rng.uniform(0.15, 0.45) * size * np.array([np.cos(rng.uniform(0, 2 * np.pi)),
                                                         np.sin(rng.uniform(0, 2 * np.pi)), 0.0])
    dragged.location = dragged.location + type(dragged.location)(shift)
    dragged.rotation_euler.z += angle
    bpy.context.view_layer.update()
    obj.shapedeform.iterations = 1  # a Viewport budget no drag of this size converges in

    # Graph positions of what is written, read straight after each write: in background mode
    # any later update re-poses with the Render budget (Blender without a window is final).
    shown = rig.pose(obj, final=False).posed.copy()
    assert rig.unsettled(bpy.context.scene) == [obj]
    handlers.refine()  # what the timer does once the updates pause
    refined = rig.get(obj).posed.copy()
    refined_mesh = checks.mesh_points(obj)  # the mesh as written, no update in between
    assert rig.unsettled(bpy.context.scene) == []

    rig.forget(obj)
    rendered = rig.pose(obj, final=True).posed  # what a render or a bake solves
    assert np.abs(refined - rendered).max() <= 1e-9 * size
    assert np.abs(checks.mesh_points(obj) - refined_mesh).max() <= 1e-6 * size
    assert np.abs(shown - rendered).max() > 1e-3 * size  # the budget did stop short
