# SPDX-License-Identifier: GPL-3.0-or-later
"""Curves posed: time from a handle move to the evaluated curve, for Bezier and poly curves and a mesh.

Each checkout (this one, and
``--compare-with DIR``) is built and installed like a user in a Python process of its own (see
``addon_speed.py``); each object is bound with two handles, and ``MOVES`` moves of one are timed
(``location`` changed, ``view_layer.update()``, then the evaluated object read as a mesh). The
table gives the median and 90th percentile over ``--rounds`` runs, the checkouts taking turns
to go first::

    .venv/bin/python benchmarks/curve_handles.py [--rounds 2] [--compare-with /tmp/before]
"""

import json
import sys
import time

import numpy as np

from addon_speed import _install, checkout_parser, checkouts, in_turns, run_worker

MOVES = 30
OBJECTS = ("text as a curve (75 letters)", "poly curve (2,000 points)", "grid mesh (40,401 vertices)")


def _text_curve():
    import bpy

    bpy.ops.object.text_add()
    bpy.context.object.data.body = "Shape Deform rigs curves " * 3
    bpy.ops.object.convert(target="CURVE")
    obj = bpy.context.active_object
    obj.data.fill_mode = "NONE"
    return obj


def _poly_curve():
    import bpy

    curve = bpy.data.curves.new("Poly", "CURVE")
    curve.dimensions, curve.fill_mode = "2D", "NONE"
    t = np.linspace(0.0, 2.0 * np.pi, 2000, endpoint=False)
    spline = curve.splines.new("POLY")
    spline.points.add(len(t) - 1)
    co = np.column_stack([3.0 * np.cos(t), np.sin(t) * (1.0 + 0.2 * np.sin(9.0 * t)), 0.0 * t, 1.0 + 0.0 * t])
    spline.points.foreach_set("co", co.astype(np.float32).ravel())
    spline.use_cyclic_u = True
    obj = bpy.data.objects.new("Poly", curve)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _grid():
    import bpy

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=200, y_subdivisions=200, size=4.0)
    return bpy.context.active_object


def worker(root, out):
    import bpy

    _install(root)
    times = {}
    for name, make in zip(OBJECTS, (_text_curve, _poly_curve, _grid)):
        bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
        obj = make()
        bpy.context.view_layer.objects.active = obj
        bpy.ops.shapedeform.bind()
        corners = np.array(obj.bound_box)
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        for x in (lo[0] + 0.1 * (hi[0] - lo[0]), hi[0] - 0.1 * (hi[0] - lo[0])):
            bpy.ops.shapedeform.add_handle(location=(x, 0.5 * (lo[1] + hi[1]), 0.0))
        handle = obj.shapedeform.handles[-1].object
        times[name] = []
        for k in range(MOVES):
            start = time.perf_counter()
            handle.location.y += 0.01 if k % 20 < 10 else -0.01
            bpy.context.view_layer.update()
            evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
            evaluated.to_mesh()
            evaluated.to_mesh_clear()
            times[name].append(time.perf_counter() - start)
    with open(out, "w", encoding="utf-8") as fh:
        json.dump(times, fh)


def main(argv=None):
    parser = checkout_parser(__doc__.splitlines()[0])
    args = parser.parse_args(argv)
    if args.worker:
        worker(args.worker, args.json)
        return 0
    designs = checkouts(__file__, args.compare_with)
    times = in_turns(designs, args.rounds, lambda root: run_worker(__file__, root))
    print(f"handle move -> evaluated, {MOVES} moves x {args.rounds} rounds")
    print("| object | checkout | ms: median | 90th percentile |")
    print("|---|---|---:|---:|")
    for measure in OBJECTS:
        for name in designs:
            ms = 1000.0 * np.array(times[name][measure])
            print(f"| {measure} | {name} | {np.median(ms):.1f} | {np.percentile(ms, 90):.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
