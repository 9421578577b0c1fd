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


def keyed_grid(name, x):
    """A grid rigged with a handle at each end, the second keyed 0.4 across from frame 1 to 10."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=x, y_subdivisions=6, size=1.0)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.transform(Matrix.Diagonal((2.0, 1.0, 1.0, 1.0)))
    _, moved = checks.bind_with_handles(obj, (-1.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    moved.keyframe_insert("location", frame=1)
    moved.location.y += 0.4
    moved.keyframe_insert("location", frame=10)
    return obj


@pytest.mark.parametrize("how", ["hidden", "modifier off"])
def test_rigs_the_viewport_does_not_show_wait_until_playback_stops(addon, monkeypatch, how):
    """Playing or scrubbing, a rig the viewport does not show is not solved (hiding characters
    did not make playback any faster: every rig was solved on every frame); once the frames
    pause it is posed, as a render poses it."""
    rig, handlers = addon.shapedeform_addon.rig, addon.shapedeform_addon.handlers
    scene = bpy.context.scene
    shown, unseen = keyed_grid("Shown", 12), keyed_grid("Unseen", 13)
    scene.frame_set(1)
    shown_before, unseen_before = cage_points(shown).copy(), cage_points(unseen).copy()
    if how == "hidden":
        unseen.hide_set(True)
    else:
        unseen.modifiers[0].show_viewport = False
    monkeypatch.setattr(handlers, "_interactive", lambda: True)  # as if the animation played
    scene.frame_set(10)
    assert np.abs(cage_points(shown) - shown_before).max() > 0.2
    assert cage_points(unseen).tobytes() == unseen_before.tobytes()
    assert rig.unsettled(scene) == [unseen]
    handlers.refine()  # what the timer does once the frames pause
    assert rig.unsettled(scene) == []
    refined = cage_points(unseen).copy()
    assert np.abs(refined - unseen_before).max() > 0.2
    rig.forget(unseen)
    rig.pose(unseen, final=True)  # what a render solves
    np.testing.assert_allclose(cage_points(unseen), refined, atol=1e-6)


def test_a_still_rig_is_not_lifted_again_on_every_frame(addon, monkeypatch):
    """A rig whose handles do not move keeps its solve from frame to frame, but its cage's
    depth was worked out again on every one (QA: 1.1 ms of each still rig's frame)."""
    rig_module = addon.shapedeform_addon.rig
    scene = bpy.context.scene
    keyed_grid("Moving", 12)
    still = keyed_grid("Still", 13)
    still.animation_data_clear()
    for item in still.shapedeform.handles:
        item.object.animation_data_clear()
    scene.frame_set(1)
    still_pose = cage_points(still).copy()
    lifted = []
    reach = rig_module.depth.automatic_reach
    monkeypatch.setattr(rig_module.depth, "automatic_reach", lambda *args: lifted.append(1) or reach(*args))
    for frame in range(2, 7):
        scene.frame_set(frame)
    assert len(lifted) == 5  # the moving rig's, once a frame
    assert cage_points(still).tobytes() == still_pose.tobytes()


def cage_points(obj):
    """The pose the rig's cage holds, (n, 3) in rig space."""
    return checks.mesh_points(obj.shapedeform.cage)


def test_every_cached_rigs_coarse_copy_outlives_a_rebuild(addon, monkeypatch):
    """Undo drops the rig cache and rebuilds each rig, which finds its coarse copy kept (making
    it is most of a rebuild). The copies were kept for the 32 last used: past 32 rigs each
    rebuild evicted the copy the next one needed, and every copy was made again on every undo."""
    rig = addon.shapedeform_addon.rig
    copies = rig._coarse_copies
    monkeypatch.setattr(copies, "kept", 2)  # as a scene with more rigs than the copies once kept
    objects = [keyed_grid(f"Grid {k}", 30 + 4 * k) for k in range(3)]
    for obj in objects:
        rig.pose(obj)
    made = dict(copies._copies)
    assert len(made) >= 3 and any(value is not None for value in made.values())
    rig.forget()  # as undo does
    for obj in objects:
        rig.pose(obj)
    assert all(copies._copies.get(key) is value for key, value in made.items())


def test_playback_looks_through_the_scene_for_rigs_once_per_frame(addon, monkeypatch):
    """Finding the scene's rigs walks its objects (5.5 ms with 5,000 Empties): playback did it
    three times a frame (posing, then twice asking whether a refine was due)."""
    rig_format, handlers = addon.shapedeform_addon.rig_format, addon.shapedeform_addon.handlers
    scene = bpy.context.scene
    keyed_grid("Shown", 12)
    scene.frame_set(1)
    walks = []
    owners = rig_format.owners
    monkeypatch.setattr(rig_format, "owners", lambda *args, **kw: walks.append(1) or owners(*args, **kw))
    monkeypatch.setattr(handlers, "_interactive", lambda: True)  # as if the animation played
    for frame in range(2, 6):
        scene.frame_set(frame)
    assert len(walks) == 4
