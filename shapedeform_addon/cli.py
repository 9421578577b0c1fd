# SPDX-License-Identifier: GPL-3.0-or-later
"""The command line: ``blender -b shot.blend -c shapedeform bake --frames 1-250``.

Registered with ``bpy.utils.register_cli_command``, so a render farm (or any job queue that
can run ``blender -b``) bakes a shot before rendering it. :func:`main` is the command itself
and can be called directly, e.g. ``main(["bake", "--frames", "1-250"])``.
"""

import argparse
import os
import re
import sys

import bpy

from . import bake, rig_format
from .errors import RigError

COMMAND = "shapedeform"

_handle = None


class _UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    """argparse without ``sys.exit``: bad arguments become a message and a return code."""

    def error(self, message):
        raise _UsageError(f"{self.prog}: error: {message}")

    def exit(self, status=0, message=None):
        if message:
            print(message, file=sys.stderr if status else sys.stdout, end="")
        raise SystemExit(status)


def frame_range(text):
    """``"1-250"`` (or ``"12"``, or ``"-10--1"`` for negative frames) as (start, end)."""
    match = re.fullmatch(r"\s*(-?\d+)\s*(?:-\s*(-?\d+)\s*)?", text)
    if match is None:
        raise argparse.ArgumentTypeError(f"'{text}' is not a frame range like 1-250")
    start = int(match.group(1))
    end = int(match.group(2)) if match.group(2) is not None else start
    try:
        bake.check_frames(start, end)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"'{text}': {err}") from None
    return start, end


def parser():
    top = _Parser(prog=f"blender -b FILE.blend -c {COMMAND}",
                  description="Shape Deform commands for batch work and render farms.")
    commands = top.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    commands.required = True
    sub = commands.add_parser("bake", help="bake rigs into keyframes and save the file",
                              description="Bake every rig of the scene (or the named ones) into "
                                          "keyframes, then save the file (or a copy with --output).")
    sub.add_argument("--frames", type=frame_range, metavar="START-END",
                     help="frames to bake, e.g. 1-250 (default: the scene's frame range)")
    sub.add_argument("--step", type=int, default=1, help="bake every n-th frame (default 1)")
    sub.add_argument("--objects", nargs="+", action="extend", metavar="NAME",
                     help="only these objects (default: every rig); may be given more than once")
    sub.add_argument("--scene", metavar="NAME", help="scene to bake (default: the file's active scene)")
    sub.add_argument("--view-layer", metavar="NAME",
                     help="view layer whose evaluation is baked (default: the scene's active one)")
    sub.add_argument("--output", metavar="FILE.blend",
                     help="save here instead of over the opened file (// is the opened file's folder)")
    return top


def _negative_ranges_joined(argv):
    """``--frames -10--1`` as ``--frames=-10--1``: argparse takes a value starting with '-' for
    an option unless it is a plain negative number."""
    joined = []
    for arg in argv:
        if joined and joined[-1] == "--frames" and re.match(r"-\d", arg):
            joined[-1] = f"--frames={arg}"
        else:
            joined.append(arg)
    return joined


def _output_path(output):
    """The absolute path ``--output`` names (``//`` relative to the opened file); None without,
    when the opened file is saved over."""
    if output is None:
        if not bpy.data.filepath:
            raise _UsageError("no .blend file is open: give it before -c (blender -b shot.blend -c ...) "
                              "or pass --output")
        return None
    if not output.strip():
        raise _UsageError("--output is empty: name a .blend file, or leave --output out to save over the opened one")
    if output.startswith("//") and not bpy.data.filepath:
        raise _UsageError(f"--output {output}: '//' is the opened file's folder, and no file is open")
    path = os.path.abspath(bpy.path.abspath(output))
    folder = os.path.dirname(path)
    if not os.path.isdir(folder):
        raise _UsageError(f"--output: the folder {folder} does not exist")
    if os.path.isdir(path):
        raise _UsageError(f"--output {path} is a folder: name a .blend file in it")
    return path


def _bake(args):
    # An empty name (a farm's unset variable) is refused, not taken for the active scene.
    scene = bpy.data.scenes.get(args.scene) if args.scene is not None else bpy.context.scene
    if scene is None:
        raise _UsageError(f"no scene named '{args.scene}' in {bpy.data.filepath or 'the file'}")
    if args.step < 1:
        raise _UsageError(f"--step must be 1 or more, got {args.step}")
    context = {"scene": scene}  # the view layer is then the window's, if the scene has it, else the first
    if args.view_layer is not None:
        context["view_layer"] = scene.view_layers.get(args.view_layer)
        if context["view_layer"] is None:
            raise _UsageError(f"no view layer named '{args.view_layer}' in scene '{scene.name}'")
    output = _output_path(args.output)
    with bpy.context.temp_override(**context):
        depsgraph = bpy.context.evaluated_depsgraph_get()  # the view layer's that will bake
    objects = _rigs_to_bake(args.objects, scene, depsgraph)
    start, end = args.frames or (scene.frame_start, scene.frame_end)
    names = ", ".join(o.name for o in objects)
    print(f"{COMMAND}: baking {bake.frames_text(start, end)} (step {args.step}) of {names}", flush=True)

    def progress(done, total):
        print(f"{COMMAND}: frame {done}/{total}", flush=True)

    with bpy.context.temp_override(**context):
        bake.bake_objects(objects, start, end, args.step, scene=scene, progress=progress)
    target = output or bpy.data.filepath
    bpy.ops.wm.save_as_mainfile(filepath=target, copy=output is not None)
    print(f"{COMMAND}: saved {target}", flush=True)


def _rigs_to_bake(names, scene, depsgraph):
    """The rig owners to bake: those ``names`` (objects, or their handles or cages) name, or
    every rig of ``scene`` with handles when ``names`` is empty."""
    if names:
        # The objects the scene shows, linked ones too (the bake refuses those by name); a handle
        # or cage stands for its rig, as in the Bake operator (an instanced rig's too). Named
        # alike, a local object wins over a linked one.
        owners = rig_format.owners(scene, depsgraph)
        parts = [h.object for o in owners for h in rig_format.present_items(o)]
        parts += [o.shapedeform.cage for o in owners if o.shapedeform.cage is not None]
        objects = sorted(rig_format.shown_objects(scene), key=lambda o: o.library is None)
        shown = {o.name: o for o in objects + parts + owners}
        missing = [name for name in names if name not in shown]
        if missing:
            raise _UsageError(f"no object named {', '.join(map(repr, missing))} in scene '{scene.name}'")
        objects = list(dict.fromkeys(rig_format.owner_of(shown[name]) or shown[name] for name in names))
        unbound = [o.name for o in objects if not o.shapedeform.is_bound]
        if unbound:
            raise _UsageError(f"not rigged with Shape Deform: {', '.join(map(repr, unbound))}")
        return objects
    # Bound objects whose rig broke (a cage deleted by hand) too: the bake then says why.
    broken = [o for o in scene.objects if o.shapedeform.is_bound and o.shapedeform.cage is None
              and o.library is None]
    objects = [o for o in rig_format.owners(scene, depsgraph) + broken if rig_format.present_items(o)]
    frozen = _linked_unbaked(scene)
    if frozen and not objects:
        raise RigError(_frozen_message(frozen))
    if not objects:
        raise _UsageError(f"scene '{scene.name}' has no rigs with handles to bake")
    if frozen:
        print(f"{COMMAND}: warning: {_frozen_message(frozen)}", file=sys.stderr, flush=True)
    return objects


def _linked_unbaked(scene):
    """The rigs ``scene`` shows that are linked without an override and have no bake: nothing
    here poses them."""
    found = [rig_format.owner_of(o) for o in rig_format.shown_objects(scene)
             if o.library is not None and o.shapedeform.is_bound]
    return [o for o in dict.fromkeys(found) if o is not None and o.library is not None
            and rig_format.present_items(o) and not rig_format.is_baked(o)]


def _frozen_message(rigs):
    one = len(rigs) == 1
    named = ", ".join(f"'{o.name}' (from '{o.library.name}')" for o in rigs)
    return (f"{named} {'is' if one else 'are'} linked without a library override and not baked in "
            f"{'its library' if one else 'their libraries'}: nothing here poses {'it' if one else 'them'}, so "
            f"{'it renders' if one else 'they render'} as the library file was saved. Bake in the library file, "
            "or make a library override here (Object > Library Override) and bake again")


def main(argv):
    """Run a command line; returns the process exit code (0 when it worked).

    Parameters
    ----------
    argv : list of str
        The arguments after ``-c shapedeform``.
    """
    try:
        args = parser().parse_args(_negative_ranges_joined(argv))
        if args.command == "bake":
            _bake(args)
    except SystemExit as done:  # --help
        return int(done.code or 0)
    except _UsageError as err:
        print(str(err), file=sys.stderr)
        return 2
    except (RigError, ValueError, RuntimeError) as err:
        print(f"{COMMAND}: failed, nothing was saved: {err}", file=sys.stderr)
        return 1
    return 0


classes = ()


def register():
    global _handle
    _handle = bpy.utils.register_cli_command(COMMAND, main)


def unregister():
    global _handle
    if _handle is not None:
        bpy.utils.unregister_cli_command(_handle)
        _handle = None
