#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Headless demo of Shape Deform: rig, animate, bake, save, and picture the result.

What it does, as an animator would in Blender, but from a script:

1. builds the extension zip from this checkout and installs it like a user, into a private
   user-resources folder (your own Blender settings are not touched);
2. rigs Blender's grease-pencil monkey and an image with alpha imported as a plane (a
   character drawn here), adds handles, keyframes them, and bakes the animation into ordinary
   keyframes;
3. saves ``demo.blend`` and writes before/after pictures of what Blender evaluated
   (``monkey.png``, ``character.png`` and ``demo.png`` side by side) into ``--out``.
"""

import argparse
import os
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


def gp_points(obj, evaluated=True):
    """World positions of all points of a grease-pencil object's current drawings, (p, 3)."""
    import bpy
    import numpy as np

    source = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()) if evaluated else obj
    chunks = []
    for layer in source.data.layers:
        frame = layer.current_frame()
        if frame is None:
            continue
        attribute = frame.drawing.attributes["position"]
        values = np.empty(len(attribute.data) * 3, dtype=np.float32)
        attribute.data.foreach_get("vector", values)
        chunks.append(values.reshape(-1, 3))
    local = np.concatenate(chunks).astype(np.float64)
    matrix = np.array(obj.matrix_world)
    return local @ matrix[:3, :3].T + matrix[:3, 3]


def gp_strokes(obj):
    """Evaluated strokes: (layer name, (k, 3) world-space polyline, cyclic) for each stroke."""
    import bpy
    import numpy as np

    source = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    matrix = np.array(obj.matrix_world)
    strokes = []
    for layer in source.data.layers:
        frame = layer.current_frame()
        if frame is None:
            continue
        drawing = frame.drawing
        attribute = drawing.attributes["position"]
        values = np.empty(len(attribute.data) * 3, dtype=np.float32)
        attribute.data.foreach_get("vector", values)
        points = values.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
        offsets = np.concatenate([[0], np.cumsum([len(stroke.points) for stroke in drawing.strokes])])
        cyclic = [stroke.cyclic for stroke in drawing.strokes]
        strokes += [(layer.name, points[a:b], c) for a, b, c in zip(offsets[:-1], offsets[1:], cyclic)]
    return strokes


def mesh_world_points(obj, evaluated=False):
    import bpy
    import numpy as np

    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data if evaluated else obj.data
    values = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", values)
    matrix = np.array(obj.matrix_world)
    return values.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]


def mesh_picture(obj):
    """Evaluated triangles in world XY and a colour per triangle sampled from its image."""
    import bpy
    import numpy as np

    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    mesh.calc_loop_triangles()
    points = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", points)
    matrix = np.array(obj.matrix_world)
    points = points.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]
    triangles = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int64)
    mesh.loop_triangles.foreach_get("vertices", triangles)
    loops = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int64)
    mesh.loop_triangles.foreach_get("loops", loops)
    uv = np.empty(len(mesh.loops) * 2)
    mesh.uv_layers.active.data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2)[loops].reshape(-1, 3, 2).mean(axis=1)
    image = next(node.image for node in obj.active_material.node_tree.nodes if node.type == "TEX_IMAGE")
    pixels = np.empty(image.size[0] * image.size[1] * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(image.size[1], image.size[0], 4)
    rows = np.clip((uv[:, 1] * image.size[1]).astype(int), 0, image.size[1] - 1)
    cols = np.clip((uv[:, 0] * image.size[0]).astype(int), 0, image.size[0] - 1)
    colours = pixels[rows, cols, :3]
    evaluated.to_mesh_clear()
    return points, triangles.reshape(-1, 3), colours


def draw(ax, obj, kind, title):
    import numpy as np

    if kind == "gp":
        for layer, stroke, cyclic in gp_strokes(obj):
            if cyclic:
                stroke = np.concatenate([stroke, stroke[:1]])
            if layer == "Fills":
                ax.fill(stroke[:, 0], stroke[:, 2], color="#f2c79a", lw=0)
            else:
                ax.plot(stroke[:, 0], stroke[:, 2], color="black", lw=1.2)
    else:
        points, triangles, colours = mesh_picture(obj)
        from matplotlib.collections import PolyCollection

        ax.add_collection(PolyCollection(points[triangles][:, :, :2], facecolors=colours, edgecolors="none"))
        ax.autoscale_view()
    for item in obj.shapedeform.handles:
        location = np.array(item.object.matrix_world.translation)
        ax.plot(location[0], location[2] if kind == "gp" else location[1], "o", color="tab:red", ms=6)
    ax.set_aspect("equal")
    ax.set_title(title)
    ax.axis("off")


def pictures(monkey, character, out):
    import bpy
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scene = bpy.context.scene
    figure, axes = plt.subplots(1, 4, figsize=(16, 4.5))
    for column, (obj, kind, name) in enumerate(((monkey, "gp", "monkey"), (character, "mesh", "character"))):
        single, pair = plt.subplots(1, 2, figsize=(9, 4.5))
        for i, frame in enumerate(FRAMES):
            scene.frame_set(frame)
            label = f"{name}, frame {frame} ({'rest' if i == 0 else 'posed'})"
            draw(pair[i], obj, kind, label)
            draw(axes[2 * column + i], obj, kind, label)
        single.tight_layout()
        single.savefig(os.path.join(out, f"{name}.png"), dpi=90)
        plt.close(single)
    figure.tight_layout()
    figure.savefig(os.path.join(out, "demo.png"), dpi=80)
    plt.close(figure)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="out", help="output folder (default: out)")
    args = parser.parse_args(argv)
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    user_resources = tempfile.mkdtemp(prefix="shapedeform-demo-")
    os.environ["BLENDER_USER_RESOURCES"] = user_resources  # before bpy loads
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
    blend = os.path.join(out, "demo.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    print(f"saved {blend}")
    pictures(monkey, character, out)
    print(f"wrote {os.path.join(out, 'demo.png')} (and monkey.png, character.png) "
          f"in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
