# SPDX-License-Identifier: GPL-3.0-or-later
"""Playback and handle moves: time per frame change and per move with many rigs in a scene.

Each checkout (this one, and ``--compare-with DIR``) is built and installed like a user in a
Python process of its own (see ``addon_speed.py``). The scene holds ``--rigs`` copies of
Blender's grease-pencil monkey, each bound with two handles; the first ``--animated`` have a
handle keyed across the face over frames 1-100; ``--props`` Empties nobody rigged stand for the
rest of a big scene. Every frame change is timed (``scene.frame_set``: the add-on's frame
handler poses the rigs, then Blender evaluates what was written), then ``MOVES`` moves of the
last rig's first handle (``location`` changed, then ``view_layer.update()``: the depsgraph
handler poses it). With ``--bake-frames N`` the animated rigs are first baked over frames 1-N
(a long shot's bake), so the frame changes time playing bakes (``--compare-with`` a checkout
that bakes otherwise). The table gives the median, 90th percentile and worst over ``--rounds``
runs, the checkouts taking turns to go first::

    .venv/bin/python benchmarks/playback.py [--rigs 20] [--animated 1] [--props 0] [--rounds 2]
        [--bake-frames 0] [--compare-with /tmp/before]
"""

import json
import sys
import time

import numpy as np

from addon_speed import _install, checkout_parser, checkouts, _monkey, in_turns, run_worker

FRAMES = range(1, 101)
MOVES = 40


def _scene(rigs, animated, props):
    """Bind ``rigs`` monkeys side by side, two handles each; key the first ``animated``; add
    ``props`` Empties."""
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    for k in range(props):
        prop = bpy.data.objects.new(f"Prop {k}", None)
        prop.location = (0.3 * (k % 100), 10.0 + 0.3 * (k // 100), 0.0)
        scene.collection.objects.link(prop)
    for k in range(rigs):
        obj = _monkey()
        obj.location.x = 3.5 * k
        bpy.context.view_layer.update()
        assert bpy.ops.shapedeform.bind() == {"FINISHED"}
        obj.shapedeform.render_iterations = obj.shapedeform.iterations  # as while working
        for z in (-0.6, 0.6):
            assert bpy.ops.shapedeform.add_handle(location=(3.5 * k, 0.0, z)) == {"FINISHED"}
            bpy.context.view_layer.objects.active = obj
        if k < animated:
            handle = obj.shapedeform.handles[1].object
            handle.keyframe_insert("location", frame=1)
            handle.location.x += 0.5
            handle.keyframe_insert("location", frame=50)
            handle.location.x -= 0.5
            handle.keyframe_insert("location", frame=100)
    scene.frame_set(1)
    return scene


def worker(root, rigs, animated, props, bake_frames, out):
    import bpy  # noqa: F401  (loads Blender, which puts addon_utils on the path)

    addon = _install(root)
    scene = _scene(rigs, animated, props)
    if bake_frames:
        baked = [o for o in scene.objects if o.shapedeform.is_bound and o.shapedeform.handles][:animated]
        addon.bake.bake_objects(baked, 1, bake_frames)
    times = {"frame change": [], "handle move": []}
    for frame in FRAMES:
        start = time.perf_counter()
        scene.frame_set(frame)
        times["frame change"].append(time.perf_counter() - start)
    handle = bpy.context.active_object.shapedeform.handles[0].object
    for k in range(MOVES):
        start = time.perf_counter()
        handle.location.x += 0.01 if k % 20 < 10 else -0.01
        bpy.context.view_layer.update()
        times["handle move"].append(time.perf_counter() - start)
    with open(out, "w", encoding="utf-8") as fh:
        json.dump(times, fh)


def main(argv=None):
    parser = checkout_parser(__doc__.splitlines()[0])
    parser.add_argument("--rigs", type=int, default=20)
    parser.add_argument("--animated", type=int, default=1)
    parser.add_argument("--props", type=int, default=0, help="Empties nobody rigged in the scene")
    parser.add_argument("--bake-frames", type=int, default=0, help="bake the animated rigs over frames 1-N first")
    args = parser.parse_args(argv)
    if args.worker:
        worker(args.worker, args.rigs, args.animated, args.props, args.bake_frames, args.json)
        return 0
    designs = checkouts(__file__, args.compare_with)
    extra = ["--rigs", str(args.rigs), "--animated", str(args.animated), "--props", str(args.props),
             "--bake-frames", str(args.bake_frames)]
    times = in_turns(designs, args.rounds, lambda root: run_worker(__file__, root, extra))
    baked = f", baked over {args.bake_frames} frames" if args.bake_frames else ""
    print(f"{args.rigs} monkeys, {args.animated} animated{baked}, {args.props} other objects; {len(FRAMES)} frames "
          f"and {MOVES} handle moves x {args.rounds} rounds")
    print("| checkout | measure | ms: median | 90th percentile | worst |")
    print("|---|---|---:|---:|---:|")
    for name, measures in times.items():
        for measure, values in measures.items():
            ms = 1000.0 * np.array(values)
            print(f"| {name} ({designs[name]}) | {measure} | {np.median(ms):.1f} | {np.percentile(ms, 90):.1f} "
                  f"| {ms.max():.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
