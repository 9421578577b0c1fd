# SPDX-License-Identifier: GPL-3.0-or-later
"""Time from moving a handle to positions written, in Blender, beside the cost of the write.

Runs under the dev venv's PyPI ``bpy``: builds and installs the extension like a user (into a
temporary user-resources folder), then on three objects -- Blender's grease-pencil monkey, a
5,000-point grease-pencil drawing and a 50,000-vertex mesh -- binds, adds two handles, moves one
repeatedly and reports the median time of:

- ``update``: ``handle.location`` changed, then ``view_layer.update()``, which runs the add-on's
  depsgraph handler (targets, solve, binding, write, depsgraph re-evaluation);
- ``solve``: the solver alone for the same targets;
- ``write``: writing the same positions back alone (one ``foreach_set``).

    .venv/bin/python benchmarks/addon_speed.py [--repeats 15]
"""

import argparse
import importlib.util
import os
import statistics
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="shapedeform-bench-")

import bpy  # noqa: E402  (after BLENDER_USER_RESOURCES)
import addon_utils  # noqa: E402
import numpy as np  # noqa: E402

MODULE = "bl_ext.user_default.shapedeform"


def install():
    spec = importlib.util.spec_from_file_location("build_extension", os.path.join(ROOT, "tools", "build_extension.py"))
    build = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build)
    platform = build.this_platform()
    zip_path = build.build([platform], tempfile.mkdtemp(prefix="shapedeform-zip-"))[platform]
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=False)
    addon_utils.enable(MODULE, default_set=True)
    return sys.modules[MODULE].shapedeform_addon


def median_ms(function, repeats):
    times = []
    for i in range(repeats):
        start = time.perf_counter()
        function(i)
        times.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times)


def gp_drawing(points=5000, strokes=50):
    """A grease-pencil object with ``points`` points in ``strokes`` wavy strokes (XY plane)."""
    data = bpy.data.grease_pencils.new("Drawing")
    layer = data.layers.new("Lines")
    drawing = layer.frames.new(bpy.context.scene.frame_current).drawing
    per = points // strokes
    drawing.add_strokes([per] * strokes)
    t = np.linspace(0.0, 1.0, per)
    rows = np.arange(strokes)[:, None] / strokes
    xyz = np.stack([np.broadcast_to(t, (strokes, per)) * 2.0,
                    rows + 0.03 * np.sin(12 * t), np.zeros((strokes, per))], axis=2)
    drawing.attributes["position"].data.foreach_set("vector", xyz.astype(np.float32).ravel())
    radius = drawing.attributes.get("radius") or drawing.attributes.new("radius", "FLOAT", "POINT")
    radius.data.foreach_set("value", np.full(per * strokes, 0.02, np.float32))
    obj = bpy.data.objects.new("Drawing", data)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def dense_mesh():
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=249, y_subdivisions=199, size=2.0)
    return bpy.context.active_object


def monkey():
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    return bpy.context.active_object


def measure(addon, name, make, repeats):
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    obj = make()
    bpy.context.view_layer.objects.active = obj
    bpy.context.view_layer.update()
    bpy.ops.shapedeform.bind()
    # Blender without a window solves with the Render budget; measure the interactive one.
    obj.shapedeform.render_iterations = obj.shapedeform.iterations
    rig = addon.rig.get(obj)
    lo, hi = (np.array(v) for v in zip(*[(min(c), max(c)) for c in zip(*[obj.matrix_world @ v.co
                                                                      for v in _corners(obj)])]))
    middle = 0.5 * (lo + hi)
    axis = int(np.argmax(hi - lo))
    ends = []
    for side in (lo, hi):
        point = middle.copy()
        point[axis] = middle[axis] + 0.8 * (side[axis] - middle[axis])
        ends.append(tuple(point))
    for location in ends:
        bpy.ops.shapedeform.add_handle(location=location)
    handle = obj.shapedeform.handles[-1].object
    bpy.context.view_layer.update()
    step = 0.002 * float(np.linalg.norm(hi - lo))

    def move(i):
        handle.location[(axis + 1) % 3] += step if i % 2 == 0 else -step
        bpy.context.view_layer.update()

    move(0)
    update = median_ms(move, repeats)
    rig = addon.rig.get(obj)
    frames = rig.frames(obj, bpy.context.evaluated_depsgraph_get())
    solve = median_ms(lambda i: rig.solve(frames, obj.shapedeform.iterations), repeats)
    points = rig.points(rig.solve(frames, obj.shapedeform.iterations))
    bind_and_lift = median_ms(lambda i: rig.points(rig.posed), repeats)
    write = median_ms(lambda i: rig.source.write(obj, points), repeats)
    assert obj.shapedeform.status == "", obj.shapedeform.status
    return {"object": name, "points": len(points), "graph": rig.graph.n, "update": update,
            "solve": solve, "bind+lift": bind_and_lift, "write": write}


def _corners(obj):
    """Bounding-box corners as objects with ``.co`` (Vector), for any object type."""
    from mathutils import Vector

    class Corner:
        def __init__(self, co):
            self.co = Vector(co)

    return [Corner(c) for c in obj.bound_box]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args(argv)
    addon = install()
    rows = [measure(addon, "grease-pencil monkey", monkey, args.repeats),
            measure(addon, "5,000-point drawing", gp_drawing, args.repeats),
            measure(addon, "50,000-vertex mesh", dense_mesh, args.repeats)]
    print(f"| object | points | graph points | handle move -> written (ms) | solve (ms) "
          f"| bind + lift to 3D (ms) | write alone (ms) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['object']} | {r['points']} | {r['graph']} | {r['update']:.1f} | {r['solve']:.1f} "
              f"| {r['bind+lift']:.2f} | {r['write']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
