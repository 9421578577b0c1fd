#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Headless demo of Shape Deform: rig, animate, bake, save, and picture the result.

What it does, as an animator would in Blender, but from a script:

1. builds the extension zip from this checkout and installs it like a user, into a private
   user-resources folder (your own Blender settings are not touched);
2. rigs Blender's grease-pencil monkey and an image with alpha imported as a plane (a
   character drawn here), adds handles, keyframes them, and bakes the animation into ordinary
   keyframes;
3. poses the character twice more with its hand across its body, with and without an overlap
   pin on the hand;
4. saves ``demo.blend`` and renders with Workbench what Blender evaluated: the rigs at the first
   and last frame (``monkey.png``, ``character.png``, and ``demo.png`` side by side) and the
   overlap without and with the pin (``overlap.png``), into ``--out``.
"""

import argparse
import os
import shutil
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ADDON = "bl_ext.user_default.shapedeform"
FRAMES = (1, 24)


def install_extension(user_resources):
    """Build this platform's zip and install it with Blender's own installer; enable it."""
    import importlib.util

    import addon_utils
    import bpy

    spec = importlib.util.spec_from_file_location("build_extension", os.path.join(ROOT, "tools", "build_extension.py"))
    build_tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build_tool)
    platform = build_tool.this_platform()
    zip_path = build_tool.build([platform], os.path.join(user_resources, "zip"))[platform]
    result = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=False)
    if result != {"FINISHED"}:
        raise RuntimeError(f"installing {zip_path} failed: {result}")
    if addon_utils.enable(ADDON, default_set=True) is None:
        raise RuntimeError(f"could not enable {ADDON}")
    print(f"installed {os.path.basename(zip_path)}")


def character_image(path, size=256):
    """An RGBA picture of a gingerbread-style character on a transparent background."""
    import numpy as np
    import shapely

    sys.path.insert(0, ROOT)
    from benchmarks.shapes import character

    rings = character()
    geometry = shapely.union_all([shapely.Polygon(r) for r in rings if _ccw(r)]).difference(
        shapely.union_all([shapely.Polygon(r) for r in rings if not _ccw(r)] or [shapely.Polygon()]))
    x0, y0, x1, y1 = geometry.bounds
    scale = (size - 16) / max(x1 - x0, y1 - y0)
    ys, xs = np.mgrid[0:size, 0:size] + 0.5
    wx, wy = (xs - 8) / scale + x0, (ys - 8) / scale + y0
    inside = shapely.contains_xy(geometry, wx.ravel(), wy.ravel()).reshape(size, size)
    edge = inside & ~shapely.contains_xy(geometry.buffer(-0.08), wx.ravel(), wy.ravel()).reshape(size, size)
    rgba = np.zeros((size, size, 4))
    rgba[..., 0] = 0.80 - 0.25 * (ys / size)
    rgba[..., 1] = 0.50 - 0.15 * (ys / size)
    rgba[..., 2] = 0.22
    rgba[edge, :3] = [0.35, 0.18, 0.08]
    stripe = inside & (np.abs(wy - 1.0) < 0.08)  # a belt, so bending shows
    rgba[stripe, :3] = [0.9, 0.9, 0.95]
    rgba[..., 3] = inside
    import bpy

    image = bpy.data.images.new("character", size, size, alpha=True)
    image.pixels.foreach_set(rgba.astype(np.float32).ravel())  # rows bottom-up, as drawn
    image.filepath_raw = path
    image.file_format = "PNG"
    image.save()
    bpy.data.images.remove(image)


def _ccw(ring):
    import numpy as np

    x, y = ring[:, 0], ring[:, 1]
    return np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y) > 0


def add_handle(obj, location):
    import bpy

    before = {item.object for item in obj.shapedeform.handles}
    with bpy.context.temp_override(object=obj, active_object=obj, selected_objects=[obj]):
        result = bpy.ops.shapedeform.add_handle(location=tuple(location))
    if result != {"FINISHED"}:
        raise RuntimeError(f"add_handle failed on {obj.name}")
    return next(item.object for item in obj.shapedeform.handles if item.object not in before)


def animate(handle, frame_to_location):
    for frame, location in frame_to_location.items():
        handle.location = location
        handle.keyframe_insert("location", frame=frame)


def bind(obj):
    import bpy

    bpy.context.view_layer.objects.active = obj
    with bpy.context.temp_override(object=obj, active_object=obj, selected_objects=[obj]):
        result = bpy.ops.shapedeform.bind()
    if result != {"FINISHED"} or not obj.shapedeform.is_bound:
        raise RuntimeError(f"bind failed on {obj.name}")


def bake(objects):
    """Bake the rigs into ordinary keyframes (shape keys, GP drawings), as the Bake button does."""
    bake_module = sys.modules[f"{ADDON}.shapedeform_addon.bake"]
    bake_module.bake_objects(objects, FRAMES[0], FRAMES[1])


def rig_monkey():
    """Blender's grease-pencil monkey (drawn in XZ): ears flap, the chin drops."""
    import bpy
    import numpy as np

    bpy.ops.object.grease_pencil_add(type="MONKEY", location=(0, 0, 0))
    monkey = bpy.context.active_object
    for layer in monkey.data.layers:
        layer.use_lights = False  # the demo's scene has no lights: show the drawing's own colours
    bind(monkey)
    points = gp_points(monkey)
    low, high = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (low + high)
    left = points[np.argmin(points[:, 0])]
    right = points[np.argmax(points[:, 0])]
    chin = points[np.argmin(points[:, 2])]
    moves = {"left ear": (left, (-0.06, 0.0, 0.12)), "right ear": (right, (0.06, 0.0, 0.12)),
             "chin": (chin, (0.0, 0.0, -0.08))}
    width = high[0] - low[0]
    # All handles first, then keys: keying moves a handle, and a handle added to a posed shape
    # holds that pose (adding a handle never moves the shape).
    handles = {name: add_handle(monkey, where) for name, (where, _) in moves.items()}
    add_handle(monkey, centre)  # a pinned handle in the middle keeps the face in place
    for name, (_, move) in moves.items():
        handle = handles[name]
        animate(handle, {FRAMES[0]: tuple(handle.location),
                         FRAMES[1]: tuple(np.asarray(handle.location) + np.asarray(move) * width)})
    return monkey


def rig_character(out):
    """A traced image plane: feet pinned, one arm raised, head tilted."""
    import bpy
    import numpy as np

    path = os.path.join(out, "character.source.png")
    character_image(path)
    bpy.ops.image.import_as_mesh_planes(files=[{"name": os.path.basename(path)}], directory=out)
    plane = bpy.context.active_object
    plane.location.x = 3.0
    bpy.context.view_layer.update()
    bind(plane)
    world = mesh_world_points(plane)
    low, high = world.min(axis=0), world.max(axis=0)
    feet = [world[np.argmin(world[:, 1] + 0.3 * world[:, 0])], world[np.argmin(world[:, 1] - 0.3 * world[:, 0])]]
    hand = world[np.argmax(world[:, 0])]
    head = world[np.argmax(world[:, 1])]
    for foot in feet:
        add_handle(plane, foot)
    size = high[1] - low[1]
    arm, top = add_handle(plane, hand), add_handle(plane, head)
    animate(arm, {FRAMES[0]: tuple(arm.location), FRAMES[1]: tuple(np.asarray(arm.location) + np.array([0.05, 0.45, 0.0]) * size)})
    animate(top, {FRAMES[0]: tuple(top.location), FRAMES[1]: tuple(np.asarray(top.location) + np.array([-0.15, -0.05, 0.0]) * size)})
    return plane


def gp_points(obj):
    """World positions of all points of a grease-pencil object's current drawings, (p, 3)."""
    import numpy as np

    world = np.array(obj.matrix_world)
    parts = []
    for layer in obj.data.layers:
        frame = layer.current_frame()
        if frame is None or frame.drawing is None:
            continue
        attribute = frame.drawing.attributes["position"]
        flat = np.empty(len(attribute.data) * 3, np.float32)
        attribute.data.foreach_get("vector", flat)
        parts.append(flat.reshape(-1, 3))
    points = np.concatenate(parts).astype(np.float64)
    return points @ world[:3, :3].T + world[:3, 3]


def mesh_world_points(obj):
    """World positions of a mesh object's own vertices, (p, 3)."""
    import numpy as np

    mesh = obj.data
    flat = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.attributes["position"].data.foreach_get("vector", flat)
    world = np.array(obj.matrix_world)
    return flat.reshape(-1, 3).astype(np.float64) @ world[:3, :3].T + world[:3, 3]


def rig_overlap(out):
    """The character again, its hand dragged across its body; a copy with an overlap pin at -1
    on the hand sends the arm behind the body."""
    import bpy
    import numpy as np

    posed = []
    for x, in_front in ((6.0, None), (9.0, -1.0)):
        bpy.ops.image.import_as_mesh_planes(files=[{"name": "character.source.png"}], directory=out)
        plane = bpy.context.active_object
        plane.location.x = x
        bpy.context.view_layer.update()
        bind(plane)
        world = mesh_world_points(plane)
        low, high = world.min(axis=0), world.max(axis=0)
        size = high[1] - low[1]
        for foot in (world[np.argmin(world[:, 1] + 0.3 * world[:, 0])], world[np.argmin(world[:, 1] - 0.3 * world[:, 0])]):
            add_handle(plane, foot)
        add_handle(plane, world[np.argmax(world[:, 1])])  # the head
        chest = 0.5 * (low + high) + np.array([0.0, 0.12, 0.0]) * size
        add_handle(plane, chest)
        hand = world[np.argmax(world[:, 0])]
        if in_front is not None:
            # Pinned at rest, where the hand is alone (once across the body, the place is both's).
            with bpy.context.temp_override(object=plane, active_object=plane, selected_objects=[plane]):
                bpy.ops.shapedeform.add_handle(location=tuple(hand - np.array([0.05, 0.0, 0.0]) * size),
                                               kind="OVERLAP")
            pin = plane.shapedeform.handles[-1].object
            pin.shapedeform.extent = 0.15
            pin.shapedeform.in_front = in_front
        arm = add_handle(plane, hand)
        arm.location = tuple(np.asarray(arm.location) + np.array([-0.55, 0.12, 0.0]) * size)
        arm.rotation_euler.z = 2.6
        bpy.context.view_layer.update()
        if plane.shapedeform.status:
            raise RuntimeError(plane.shapedeform.status)
        posed.append(plane)
    return posed


def _camera(name, target, width, front_view=False):
    """An orthographic camera framing ``width`` around ``target``: from above, or from the front
    (looking along +Y) for grease pencil drawn in XZ."""
    import math

    import bpy

    data = bpy.data.cameras.new(name)
    data.type, data.ortho_scale = "ORTHO", width
    camera = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(camera)
    if front_view:
        camera.location = (target[0], target[1] - 10.0, target[2])
        camera.rotation_euler = (math.pi / 2, 0.0, 0.0)
    else:
        camera.location = (target[0], target[1], target[2] + 10.0)
    return camera


def render(camera, objects, path, size=360):
    """Render only ``objects`` through ``camera`` with Workbench, flat and textured, to ``path``."""
    import bpy

    scene = bpy.context.scene
    shown = {o.name: o.hide_render for o in scene.objects}
    for o in scene.objects:
        o.hide_render = o.type != "CAMERA" and o not in objects
    scene.camera = camera
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    shading = scene.display.shading
    shading.light, shading.color_type, shading.background_type = "FLAT", "TEXTURE", "VIEWPORT"
    shading.background_color = (1.0, 1.0, 1.0)
    scene.render.filepath = path
    scene.render.image_settings.file_format = "PNG"
    bpy.ops.render.render(write_still=True)
    for name, hidden in shown.items():
        scene.objects[name].hide_render = hidden


def _frame(points, front_view=False, margin=1.25):
    import numpy as np

    low, high = points.min(axis=0), points.max(axis=0)
    extent = (high - low)[[0, 2]] if front_view else (high - low)[:2]
    return 0.5 * (low + high), margin * float(extent.max())


def pictures(monkey, character, overlap, out):
    """Blender's own renders (Workbench) of the rigs at the first and last frame, and of the
    overlap with and without a pin, laid out side by side."""
    import bpy
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scene = bpy.context.scene
    scene.frame_set(FRAMES[0])
    monkey_view = _camera("Monkey View", *_frame(gp_points(monkey), front_view=True), front_view=True)
    character_view = _camera("Character View", *_frame(mesh_world_points(character)))
    renders = {}
    for obj, camera, name in ((monkey, monkey_view, "monkey"), (character, character_view, "character")):
        for frame in FRAMES:
            scene.frame_set(frame)
            path = os.path.join(out, f"{name}_{frame}.png")
            render(camera, [obj], path)
            renders[name, frame] = path
    scene.frame_set(FRAMES[0])
    for obj, label in zip(overlap, ("no pin", "pin")):
        centre, width = _frame(mesh_world_points(obj))
        path = os.path.join(out, f"overlap_{label.replace(' ', '_')}.png")
        render(_camera(f"{obj.name} View", centre, width), [obj], path)
        renders["overlap", label] = path

    def panel(ax, path, title):
        ax.imshow(plt.imread(path))
        ax.set_title(title)
        ax.axis("off")

    figure, axes = plt.subplots(1, 4, figsize=(16, 4.5))
    for column, name in enumerate(("monkey", "character")):
        single, pair = plt.subplots(1, 2, figsize=(9, 4.5))
        for i, frame in enumerate(FRAMES):
            title = f"{name}, frame {frame} ({'rest' if i == 0 else 'posed'})"
            panel(pair[i], renders[name, frame], title)
            panel(axes[2 * column + i], renders[name, frame], title)
        single.tight_layout()
        single.savefig(os.path.join(out, f"{name}.png"), dpi=90)
        plt.close(single)
    figure.tight_layout()
    figure.savefig(os.path.join(out, "demo.png"), dpi=80)
    plt.close(figure)
    figure, pair = plt.subplots(1, 2, figsize=(9, 4.5))
    panel(pair[0], renders["overlap", "no pin"], "hand across the body: in front (automatic)")
    panel(pair[1], renders["overlap", "pin"], "an overlap pin at -1 on the hand: behind")
    figure.tight_layout()
    figure.savefig(os.path.join(out, "overlap.png"), dpi=90)
    plt.close(figure)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="out", help="output folder (default: out)")
    args = parser.parse_args(argv)
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    user_resources = tempfile.mkdtemp(prefix="shapedeform-demo-")
    os.environ["BLENDER_USER_RESOURCES"] = user_resources  # before bpy loads
    try:
        return run(out, user_resources)
    finally:
        # The installed extension and its wheels take a few hundred MB.
        shutil.rmtree(user_resources, ignore_errors=True)


def run(out, user_resources):
    """Rig, bake, save and draw into ``out``, with the extension installed in ``user_resources``."""
    import bpy

    start = time.perf_counter()
    print(f"Blender {bpy.app.version_string}, Python {sys.version.split()[0]}")
    install_extension(user_resources)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = FRAMES
    scene.frame_set(FRAMES[0])
    monkey = rig_monkey()
    print(f"rigged the grease-pencil monkey: {len(monkey.shapedeform.handles)} handles")
    character = rig_character(out)
    print(f"rigged the traced image plane: {len(character.shapedeform.handles)} handles")
    bake([monkey, character])
    print(f"baked frames {FRAMES[0]}-{FRAMES[1]}")
    overlap = rig_overlap(out)
    print("rigged the character twice more, its hand across its body, with and without an overlap pin")
    blend = os.path.join(out, "demo.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    print(f"saved {blend}")
    pictures(monkey, character, overlap, out)
    print(f"wrote {os.path.join(out, 'demo.png')} (and monkey.png, character.png, overlap.png) "
          f"in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
