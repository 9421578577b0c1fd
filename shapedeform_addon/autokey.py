# SPDX-License-Identifier: GPL-3.0-or-later
"""Auto-keying a handle the drag moved, as Blender's auto-keying keys an object moved with G.

Blender's own keying of a moved object lives in its transform code, which a Python operator
cannot call: :func:`key_moved` follows it setting by setting (Replace mode, the active keying
set, Only Insert Needed and Available, Visual and Cycle-Aware keying), so that a handle dragged
with the drag operator is keyed as the same handle moved with G.
"""

import traceback
from types import SimpleNamespace

import bpy

from . import compat


def key_moved(context, handle):
    """Key ``handle``'s move as Blender's auto-keying keys an object moved with G: at the
    (sub)frame shown, with the timeline's key type; in Replace mode only keys there already;
    through the active keying set when Only Active Keying Set is on; else location,
    rotation and scale, or with Only Insert Needed the location alone where it changed; and
    honouring Only Insert Available, Visual Keying and Cycle-Aware Keying. Returns whether
    anything was keyed."""
    scene = context.scene
    tools, edit = scene.tool_settings, context.preferences.edit
    frame = scene.frame_current_final
    if tools.auto_keying_mode == "REPLACE_KEYS" and round(_action_frame(handle, scene), 2) not in _key_frames(handle):
        return False
    keying_set = scene.keying_sets_all.active
    if tools.use_keyframe_insert_keyingset and keying_set is not None:
        return _key_with_keying_set(context, handle, keying_set)
    flags = {"INSERTKEY_AVAILABLE": edit.use_keyframe_insert_available,
             "INSERTKEY_NEEDED": edit.use_auto_keyframe_insert_needed,
             "INSERTKEY_VISUAL": edit.use_visual_keying,
             "INSERTKEY_CYCLE_AWARE": tools.use_keyframe_cycle_aware,
             "INSERTKEY_REPLACE": tools.auto_keying_mode == "REPLACE_KEYS"}
    options = {flag for flag, on in flags.items() if on}
    paths = ["location"] if edit.use_auto_keyframe_insert_needed else ["location", _ROTATIONS.get(
        handle.rotation_mode, "rotation_euler"), "scale"]
    keyed = [handle.keyframe_insert(path, frame=frame, keytype=tools.keyframe_type, options=options) for path in paths]
    return any(keyed)


def _key_with_keying_set(context, handle, keying_set):
    """Key ``handle`` through ``keying_set`` as auto-keying does: by Blender's own operator in a
    3D viewport (its poll wants an area, which a script's context may lack), else (no window
    shows one, or the operator refused) by keying the set's paths one by one
    (:func:`_key_paths`). Returns whether anything was keyed."""
    viewport = _viewport(context)
    if viewport is not None:
        try:
            with context.temp_override(**viewport, active_object=handle, object=handle, selected_objects=[handle],
                                       selected_editable_objects=[handle]):
                return bpy.ops.anim.keyframe_insert_by_name(type=keying_set.bl_idname) == {"FINISHED"}
        except RuntimeError:  # its poll, or an error it reported: the paths say what they can key
            pass
    return _key_paths(context, handle, keying_set)


def _viewport(context):
    """Context members that put an operator in a 3D viewport: none for the context's own area
    when it is one, else the first a window shows; None when no window shows one."""
    if context.area is not None and context.area.type == "VIEW_3D":
        return {}
    manager = context.window_manager
    windows = ([context.window] if context.window is not None else []) + list(manager.windows if manager else ())
    for window in windows:
        areas = window.screen.areas if window.screen is not None else ()
        area = next((a for a in areas if a.type == "VIEW_3D"), None)
        if area is not None:
            region = next((r for r in area.regions if r.type == "WINDOW"), None)
            return {"window": window, "area": area, "region": region}
    return None


def _key_paths(context, handle, keying_set):
    """Key ``keying_set``'s paths one by one as Blender applies a keying set (it needs no area):
    at the (sub)frame shown, with the timeline's key type, Visual Keying, Cycle-Aware Keying
    and Only Insert Needed as the set and each path override them, into the F-Curve group each
    path names. A set relative to the selection (the built-in ones) keys the paths it makes for
    ``handle``. Returns whether anything was keyed."""
    scene, edit = context.scene, context.preferences.edit
    preferred = {"INSERTKEY_VISUAL": edit.use_visual_keying, "INSERTKEY_NEEDED": edit.use_keyframe_insert_needed,
                 "INSERTKEY_CYCLE_AWARE": scene.tool_settings.use_keyframe_cycle_aware}
    options = _overridden(preferred, keying_set)
    keyed = False
    for path in _keying_set_paths(context, handle, keying_set):
        if path.id is None:  # a path the user has not finished: Blender skips it too
            continue
        group = {"NAMED": path.group, "KEYINGSET": keying_set.bl_label}.get(path.group_method, "")
        try:
            keyed |= path.id.keyframe_insert(
                path.data_path, index=-1 if path.use_entire_array else path.array_index,
                frame=scene.frame_current_final, group=group, keytype=scene.tool_settings.keyframe_type,
                options={flag for flag, on in _overridden(options, path).items() if on})
        except (TypeError, ValueError, RuntimeError):  # a path that resolves no more: the others still key
            continue
    return keyed


def _overridden(options, settings):
    """``options`` ({insert-key flag: on}) with the Only Insert Needed and Visual Keying that
    ``settings`` (a keying set, or one of its paths) override."""
    options = dict(options)
    for flag, name in (("INSERTKEY_NEEDED", "needed"), ("INSERTKEY_VISUAL", "visual")):
        if getattr(settings, f"use_insertkey_override_{name}"):
            options[flag] = getattr(settings, f"use_insertkey_{name}")
    return options


def _keying_set_paths(context, handle, keying_set):
    """The paths ``keying_set`` keys for ``handle``: its own when absolute, else those its type
    makes for ``handle`` (the built-in sets' iterators read the context's area, their generators
    do not)."""
    if keying_set.is_path_absolute:
        return list(keying_set.paths)
    made = _MadePaths()
    if keying_set.type_info is not None:  # None: its type's add-on is not enabled here
        try:
            keying_set.type_info.generate(context, SimpleNamespace(paths=made), handle)
        except Exception:  # a script's keying set that fails keys nothing, as in Blender, which prints why
            traceback.print_exc()
    return made.paths


class _MadePaths:
    """Stands in for a keying set's paths while its type makes them: each added is kept with the
    attributes of a ``KeyingSetPath`` (overriding no option)."""

    def __init__(self):
        self.paths = []

    def add(self, target_id, data_path, index=-1, group_method="KEYINGSET", group_name=""):
        path = SimpleNamespace(id=target_id, data_path=data_path, array_index=max(index, 0),
                               use_entire_array=index < 0, group_method=group_method, group=group_name,
                               use_insertkey_override_needed=False, use_insertkey_needed=False,
                               use_insertkey_override_visual=False, use_insertkey_visual=False)
        self.paths.append(path)
        return path


# The property an object's rotation is keyed on, by rotation mode (Euler modes otherwise).
_ROTATIONS = {"QUATERNION": "rotation_quaternion", "AXIS_ANGLE": "rotation_axis_angle"}


def _action_frame(obj, scene):
    """The scene's frame in the time of ``obj``'s action: an NLA strip in tweak mode maps it
    (QA: Replace keyed nothing there, comparing the scene's frame with the action's keys)."""
    frame = scene.frame_current_final
    animation = obj.animation_data
    if animation is None or not animation.use_tweak_mode:
        return frame
    return animation.nla_tweak_strip_time_to_scene(frame, invert=True)


def _key_frames(obj):
    """The frames ``obj``'s own action has keys on, for its slot (to 1/100 of a frame, as
    Blender tells a key on a frame)."""
    animation = obj.animation_data
    if animation is None or animation.action is None:
        return set()
    bag = compat.channelbag(animation.action, animation.action_slot)
    curves = [] if bag is None else bag.fcurves
    return {round(key.co[0], 2) for curve in curves for key in curve.keyframe_points}
