# SPDX-License-Identifier: GPL-3.0-or-later
"""Time from moving a handle to what Blender evaluates, and per baked frame, in Blender.

Runs under the dev venv's PyPI ``bpy`` 5.0 or later (the drawings are made through
``bpy.data.grease_pencils``, which 4.5 still gives the legacy type). Each design of the extension is built from its checkout
and installed like a user, in a Python process of its own with its own temporary
``BLENDER_USER_RESOURCES`` (every version has the id ``shapedeform``, so two cannot share one
process). On five objects -- Blender's grease-pencil monkey, a 1,200-point and a 5,000-point
grease-pencil drawing, a 50,000-vertex mesh, and a cut-out puppet (a body and an arm lying over
it, one mesh in two islands that is its own graph, so its rig keeps its vertices' islands) --
it binds, adds two handles at the same places,
drags one the same way, and reports medians of:

- ``update``: ``handle.location`` changed, then ``view_layer.update()``: the add-on's depsgraph
  handler solves and writes, and the depsgraph evaluates what was written (for the cage design,
  the cage and the object's Shape Deform modifier). Solves use the Viewport iteration budget.
- ``solve``: the solver alone for the same handle frames.
- ``map to 3D``: the solved graph to what is written (cage design: the cage's points; direct
  design: the dense binding to every point of the object, lifted to 3D).
- ``write``: writing those points alone (cage design: the cage; direct design: the object's data).
- ``evaluate``: ``view_layer.update()`` alone after a write (the add-on's handler held off), i.e.
  what Blender spends showing a written pose (cage design: the Geometry Nodes modifier).
- ``bake``: :func:`shapedeform_addon.bake.bake_objects` over ``--bake-frames`` frames of a
  handle keyframed across the shape, per frame (Render iteration budget, as a bake solves), and
  how much of it is the final write of the keys.

``--compare-with DIR`` measures a second checkout (e.g. the direct-write design,
``git worktree add /tmp/old_design 0e6c3b0``) in the same run and prints both side by side.
Rounds alternate the two designs (``--rounds``) so that a load change on the machine hits both;
the table gives the median over rounds of each measure's median over ``--repeats``::

    .venv/bin/python benchmarks/addon_speed.py [--repeats 21] [--bake-frames 50] [--rounds 1]
        [--compare-with /tmp/old_design] [--doc docs/addon_speed.md]
"""

import argparse
import datetime
import importlib.util
import json
import os
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MODULE = "bl_ext.user_default.shapedeform"
# The goal for handle move -> evaluated (one frame at 60 Hz).
GOAL_MS = 16.0

# Measures in table order: (key, label).
MEASURES = (("update", "handle move -> evaluated"), ("solve", "solve"), ("map", "map to 3D"),
            ("write", "write"), ("evaluate", "evaluate"), ("bake", "bake, per frame"),
            ("bake_keys", "bake: writing keys, per frame"))

# Objects by name, in table order; the worker builds them (see ``_objects``).
OBJECT_NAMES = ("grease-pencil monkey", "1,200-point drawing", "5,000-point drawing", "50,000-vertex mesh",
                "puppet in 2 islands")


# -- the worker: one design, in its own process -----------------------------------------------

def _median_ms(times):
    return 1000.0 * statistics.median(times)


def _timed(function, repeats, prepare=None):
    """Median ms of ``function(i)`` over ``repeats`` calls; ``prepare(i)`` runs untimed before each."""
    times = []
    for i in range(repeats):
        if prepare is not None:
            prepare(i)
        start = time.perf_counter()
        function(i)
        times.append(time.perf_counter() - start)
    return _median_ms(times)


def _install(root):
    """Build the extension of checkout ``root`` and install and enable it; its ``shapedeform_addon``."""
    import addon_utils
    import bpy

    spec = importlib.util.spec_from_file_location("build_extension", os.path.join(root, "tools", "build_extension.py"))
    build = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build)
    target = build.this_platform()
    with tempfile.TemporaryDirectory(prefix="shapedeform-zip-") as folder:
        zip_path = build.build([target], folder)[target]
        bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=False)
    addon_utils.enable(MODULE, default_set=True)
    return sys.modules[MODULE].shapedeform_addon


def checkout_parser(description, rounds=2):
    """An argument parser with the options every checkout-against-checkout benchmark takes:
    ``--rounds``, ``--compare-with DIR`` and the worker's hidden ``--worker`` and ``--json``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--rounds", type=int, default=rounds)
    parser.add_argument("--compare-with", metavar="DIR")
    parser.add_argument("--worker", metavar="ROOT", help=argparse.SUPPRESS)
    parser.add_argument("--json", help=argparse.SUPPRESS)
    return parser


def checkouts(script, compare_with=None):
    """{name: root} of the checkouts to time: the one holding ``script``, and ``compare_with``."""
    designs = {"this checkout": os.path.dirname(os.path.dirname(os.path.abspath(script)))}
    if compare_with:
        designs["--compare-with"] = os.path.abspath(compare_with)
    return designs


def run_worker(script, root, extra=()):
    """``script --worker root --json OUT extra`` in a Python process of its own with user
    resources of its own (a clean install of ``root``'s extension); the JSON it wrote."""
    with tempfile.TemporaryDirectory(prefix="shapedeform-worker-") as tmp:
        out = os.path.join(tmp, "times.json")
        env = dict(os.environ, BLENDER_USER_RESOURCES=os.path.join(tmp, "user"))
        proc = subprocess.run([sys.executable, os.path.abspath(script), "--worker", root, "--json", out, *extra],
                              env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise SystemExit(f"{os.path.basename(script)} on {root} failed:\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}")
        with open(out, encoding="utf-8") as fh:
            return json.load(fh)


def in_turns(designs, rounds, run):
    """{design: {measure: [seconds]}}: ``run(root)`` of every design ({name: root}) ``rounds``
    times, each first in every other round (the one run second was measured up to a fifth
    faster when the same one always went first)."""
    times = {name: {} for name in designs}
    order = list(designs.items())
    for round_ in range(rounds):
        for name, root in order if round_ % 2 == 0 else order[::-1]:
            for measure, values in run(root).items():
                times[name].setdefault(measure, []).extend(values)
    return times


def _gp_drawing(points, strokes):
    """A grease-pencil object with ``points`` points in ``strokes`` wavy strokes (XY plane)."""
    import bpy
    import numpy as np

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


def _monkey():
    import bpy

    bpy.ops.object.grease_pencil_add(type="MONKEY")
    return bpy.context.active_object


def _dense_mesh():
    import bpy

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=249, y_subdivisions=199, size=2.0)  # 50,000 vertices
    return bpy.context.active_object


def _puppet(columns=40):
    """A body (2 x 1, ``columns`` x ``columns / 2`` quads) and an arm lying over it to x = 3,
    as one mesh: Bind makes it its own graph and gives its vertices their islands."""
    import bpy
    import numpy as np

    verts, faces = [], []
    for nx, ny, width, height, x0, y0 in ((columns, columns // 2, 2.0, 1.0, 0.0, 0.0),
                                          (columns, columns // 4, 1.8, 0.4, 1.2, 0.3)):
        x, y = np.meshgrid(np.linspace(x0, x0 + width, nx + 1), np.linspace(y0, y0 + height, ny + 1))
        corner = len(verts) + np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)
        faces += np.stack([corner, corner + 1, corner + nx + 2, corner + nx + 1], axis=-1).reshape(-1, 4).tolist()
        verts += np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1).tolist()
    mesh = bpy.data.meshes.new("Puppet")
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new("Puppet", mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.select_set(True)
    return obj


def _objects():
    return dict(zip(OBJECT_NAMES, (_monkey, lambda: _gp_drawing(1200, 40), lambda: _gp_drawing(5000, 50),
                                   _dense_mesh, _puppet)))


def _evaluated_points(obj):
    """Every point of ``obj`` as Blender evaluated it, (p, 3) float32 (mesh or grease pencil)."""
    import bpy
    import numpy as np

    data = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    if obj.type == "MESH":
        attributes = [data.attributes["position"]]
    else:
        attributes = [layer.current_frame().drawing.attributes["position"] for layer in data.layers
                      if layer.current_frame() is not None]
    parts = []
    for attribute in attributes:
        flat = np.empty(3 * len(attribute.data), np.float32)
        attribute.data.foreach_get("vector", flat)
        parts.append(flat.reshape(-1, 3))
    return np.concatenate(parts)


class _Design:
    """What differs between the two designs, behind one face.

    The cage design (``rig_format`` exists) poses a cage that a Geometry Nodes modifier maps the
    object through; the direct design writes every point of the object.
    """

    def __init__(self, addon):
        self.addon = addon
        self.cage = hasattr(addon, "rig_format")
        self.name = "cage + Geometry Nodes modifier" if self.cage else "direct write"

    def map(self, rig, positions):
        return rig.cage_points(positions) if self.cage else rig.points(positions)

    def write(self, obj, rig, points):
        if self.cage:
            self.addon.rig_format.write_pose(obj.shapedeform.cage, points)
        else:
            rig.source.write(obj, points)


def measure(design, name, make, repeats, bake_frames):
    """Every measure of the module docstring for one object; a dict of ms and sizes."""
    import bpy
    import numpy as np
    from mathutils import Vector

    addon = design.addon
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    scene.frame_set(1)
    obj = make()
    bpy.context.view_layer.objects.active = obj
    bpy.context.view_layer.update()
    bpy.ops.shapedeform.bind()
    settings = obj.shapedeform
    render_iterations = settings.render_iterations
    # Blender without a window solves with the Render budget; a drag runs on the Viewport one.
    settings.render_iterations = settings.iterations
    corners = np.array([obj.matrix_world @ Vector(c) for c in obj.bound_box])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    # The handles sit on the longest axis; the drag goes along the other in-plane axis (a drag
    # out of the shape's plane would not move the pose at all).
    axis, across = (int(a) for a in np.argsort(hi - lo)[::-1][:2])
    middle = 0.5 * (lo + hi)
    for side in (lo, hi):
        point = middle.copy()
        point[axis] = middle[axis] + 0.8 * (side[axis] - middle[axis])
        bpy.ops.shapedeform.add_handle(location=tuple(point))
    handle = settings.handles[-1].object
    view_layer = bpy.context.view_layer
    view_layer.update()
    rest = _evaluated_points(obj)

    # A drag already under way (a fifth of the size), then steps of 1% of the size per event.
    handle.location[across] += 0.2 * size
    view_layer.update()

    def move(i):
        handle.location[across] += 0.01 * size
        view_layer.update()

    update = _timed(move, repeats)
    assert settings.status == "", settings.status
    moved = float(np.abs(_evaluated_points(obj) - rest).max())
    assert moved > 0.1 * size, f"{name}: the evaluated shape did not follow the handle ({moved})"

    rig = addon.rig.get(obj)
    frames = rig.frames(obj, bpy.context.evaluated_depsgraph_get())
    iterations = settings.iterations
    targets = sys.modules[MODULE].solver.rigging.handles.region_targets(frames, rig.offsets, rig.owners)
    # The deformer's own solve: the rig would hand back its last solve for the same targets.
    solve = _timed(lambda i: rig.deformer.solve(targets, max_iterations=iterations), repeats)
    posed = rig.solve(frames, iterations)
    # Iterations of that solve: the two designs must solve the same problem to be compared.
    solution = rig.deformer.solve(targets, max_iterations=iterations)
    points = np.ascontiguousarray(design.map(rig, posed))
    map_ms = _timed(lambda i: design.map(rig, posed), repeats)
    write = _timed(lambda i: design.write(obj, rig, points), repeats)
    # Two poses in turn, so that every evaluation has something new to show; the add-on's
    # handler is held off, so only Blender's evaluation is timed.
    other = np.ascontiguousarray(design.map(rig, rig.graph.points.copy()))
    handlers = addon.handlers
    handlers._busy = True
    try:
        evaluate = _timed(lambda i: view_layer.update(), repeats,
                          prepare=lambda i: design.write(obj, rig, points if i % 2 else other))
    finally:
        handlers._busy = False
    result = {"object": name, "points": len(rest), "graph": int(rig.graph.n),
              "written": len(points), "update": update, "solve": solve, "map": map_ms,
              "write": write, "evaluate": evaluate,
              "iterations": int(solution.iterations), "targets": targets.round(6).tolist()}
    if bake_frames:
        result.update(_bake(addon, obj, handle, across, size, render_iterations, bake_frames))
    return result


def _bake(addon, obj, handle, across, size, render_iterations, frames):
    """ms per frame of a bake of ``frames`` frames of ``handle`` keyframed across the shape."""
    import bpy

    obj.shapedeform.render_iterations = render_iterations  # a bake solves with the Render budget
    scene = bpy.context.scene
    scene.frame_set(1)
    handle.keyframe_insert("location", frame=1)
    handle.location[across] += 0.3 * size
    handle.keyframe_insert("location", frame=frames)
    scene.frame_set(1)
    stepped = {}

    def progress(done, total):
        if done == total:
            stepped["at"] = time.perf_counter()

    start = time.perf_counter()
    baked = addon.bake.bake_objects([obj], 1, frames, progress=progress)
    end = time.perf_counter()
    assert baked, "the bake did not finish"
    return {"bake": 1000.0 * (end - start) / frames, "bake_keys": 1000.0 * (end - stepped["at"]) / frames,
            "bake_frames": frames}


def worker(args):
    """Measure the design of checkout ``args.worker`` and write the results as JSON."""
    import bpy

    design = _Design(_install(args.worker))
    makers = _objects()
    rows = [measure(design, name, makers[name], args.repeats, args.bake_frames)
            for name in OBJECT_NAMES if not args.objects or name in args.objects]
    result = {"design": design.name, "bpy": bpy.app.version_string, "rows": rows}
    with open(args.json, "w", encoding="utf-8") as fh:
        json.dump(result, fh)
    return 0


# -- the driver: one process per design and round, then the table ----------------------------

def _run_worker(root, args):
    """Run one design in a fresh Python with its own user resources; its JSON results."""
    with tempfile.TemporaryDirectory(prefix="shapedeform-bench-") as tmp:
        out = os.path.join(tmp, "result.json")
        env = dict(os.environ, BLENDER_USER_RESOURCES=os.path.join(tmp, "user"))
        cmd = [sys.executable, os.path.abspath(__file__), "--worker", root, "--json", out,
               "--repeats", str(args.repeats), "--bake-frames", str(args.bake_frames)]
        for name in args.objects or ():
            cmd += ["--object", name]
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise SystemExit(f"measuring {root} failed:\n{proc.stdout[-4000:]}{proc.stderr[-4000:]}")
        with open(out, encoding="utf-8") as fh:
            return json.load(fh)


def _commit(root):
    proc = subprocess.run(["git", "-C", root, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return proc.stdout.strip() or "?"


def _combine(runs):
    """One result from rounds of the same design: each measure's median over rounds."""
    first = runs[0]
    rows = []
    for i, row in enumerate(first["rows"]):
        combined = dict(row)
        for key, _ in MEASURES:
            if key in row:
                combined[key] = statistics.median(run["rows"][i][key] for run in runs)
        rows.append(combined)
    return dict(first, rows=rows)


def _ms(value):
    return "-" if value is None else (f"{value:.2f}" if value < 10 else f"{value:.1f}")


def table(new, old=None):
    """The markdown table: one row per object and measure; old and new side by side."""
    head = f"| object | points | graph points | measure | {new['design']} (ms)"
    rule = "|---|---:|---:|---|---:"
    if old is not None:
        head += f" | {old['design']} (ms) | new / old"
        rule += "|---:|---:"
    lines = [head + " |", rule + "|"]
    old_rows = {r["object"]: r for r in old["rows"]} if old is not None else {}
    for row in new["rows"]:
        before = old_rows.get(row["object"])
        first = f"| {row['object']} | {row['points']:,} | {row['graph']:,}"
        for key, label in MEASURES:
            if key not in row:
                continue
            line = f"{first} | {label} | {_ms(row[key])}"
            if old is not None:
                value = before.get(key) if before else None
                ratio = f"{row[key] / value:.2f}" if value else "-"
                line += f" | {_ms(value)} | {ratio}"
            lines.append(line + " |")
            first = "| | |"
    return "\n".join(lines)


def same_problem(new, old):
    """A line per object saying whether both designs solved the same targets, and in how many
    iterations (else the comparison would not be fair)."""
    import numpy as np

    lines = []
    old_rows = {r["object"]: r for r in old["rows"]}
    for row in new["rows"]:
        before = old_rows.get(row["object"])
        if before is None:
            continue
        gap = float(np.abs(np.subtract(row["targets"], before["targets"])).max())
        lines.append(f"- {row['object']}: handle targets differ by {gap:.1e} between the designs; "
                     f"the last pose took {row['iterations']} (new) and {before['iterations']} (old) "
                     f"solver iterations.")
    return "\n".join(lines)


def verdict(new):
    """One line per goal object: within :data:`GOAL_MS` or not."""
    lines = []
    for row in new["rows"]:
        if row["object"] in ("1,200-point drawing", "50,000-vertex mesh"):
            met = "met" if row["update"] <= GOAL_MS else "missed"
            lines.append(f"- {row['object']}: handle move -> evaluated {_ms(row['update'])} ms, "
                         f"goal {GOAL_MS:.0f} ms {met}.")
    return "\n".join(lines)


def _cpu():
    """The processor's model name (Linux), else what ``platform`` knows."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.system()


def driver(args):
    designs = [("new", ROOT)] + ([("old", os.path.abspath(args.compare_with))] if args.compare_with else [])
    for _, root in designs[1:]:
        wheels = os.path.join(root, "wheels")
        if not os.path.exists(wheels) and os.path.isdir(os.path.join(ROOT, "wheels")):
            # Share this checkout's wheel cache: the build would otherwise download every wheel.
            os.symlink(os.path.realpath(os.path.join(ROOT, "wheels")), wheels)
    runs = {label: [] for label, _ in designs}
    # Other processes share the machine: their load is reported beside the timings.
    load_before = os.getloadavg()[0]
    for r in range(args.rounds):
        # Alternate which design goes first, so a drift in the machine's load hits both alike.
        for label, root in (designs if r % 2 == 0 else designs[::-1]):
            print(f"round {r + 1}/{args.rounds}: measuring {label} ({root})", file=sys.stderr, flush=True)
            runs[label].append(_run_worker(root, args))
    new = _combine(runs["new"])
    old = _combine(runs["old"]) if "old" in runs else None
    machine = (f"{_cpu()}, {os.cpu_count()} cores, {platform.system()} {platform.machine()}, "
               f"Python {platform.python_version()}, bpy {new['bpy']}")
    command = " ".join(shlex.quote(a) for a in [os.path.relpath(sys.executable, ROOT)
                                                 if sys.executable.startswith(ROOT) else sys.executable,
                                                 "benchmarks/addon_speed.py"] + sys.argv[1:])
    header = [f"Command: `{command}`",
              f"Machine: {machine}",
              f"Date: {datetime.date.today().isoformat()}",
              f"new: {ROOT} at {_commit(ROOT)}" + (f"; old: {designs[1][1]} at {_commit(designs[1][1])}" if old else ""),
              f"Load average (1 min) at start and end: {load_before:.1f}, {os.getloadavg()[0]:.1f}",
              f"{args.repeats} repeats per measure, median; {args.rounds} round(s), median of the rounds' medians; "
              f"bake of {args.bake_frames} frames."]
    parts = ["\n\n".join(header), "", table(new, old), "", verdict(new)]
    if old is not None:
        parts += ["", same_problem(new, old)]
    text = "\n".join(parts)
    print(text)
    if args.doc:
        with open(args.doc, "w", encoding="utf-8") as fh:
            fh.write("# Add-on speed: handle move to what Blender evaluates, and baking\n\n"
                     "Written by `benchmarks/addon_speed.py`; see its docstring for what each measure is.\n\n"
                     + text + "\n")
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=21, help="timings per measure (median)")
    parser.add_argument("--bake-frames", type=int, default=50, help="frames baked (0: no bake)")
    parser.add_argument("--rounds", type=int, default=1, help="runs of each design, alternating")
    parser.add_argument("--compare-with", metavar="DIR", help="another checkout, measured beside this one")
    parser.add_argument("--doc", metavar="PATH", help="also write the tables to this markdown file")
    parser.add_argument("--object", dest="objects", action="append", choices=OBJECT_NAMES,
                        help="measure only this object (repeatable)")
    parser.add_argument("--worker", metavar="ROOT", help=argparse.SUPPRESS)
    parser.add_argument("--json", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    return worker(args) if args.worker else driver(args)


if __name__ == "__main__":
    sys.exit(main())
