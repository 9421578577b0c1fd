# SPDX-License-Identifier: GPL-3.0-or-later
"""Baking: the live deformation turned into ordinary Blender animation.

A bake poses every frame of a range (the frame's pose depends only on the handles at that
frame, so the order does not matter), keeps what it computed in memory, and only when every
frame is done, and every object's write has been checked, replaces the previous bake of each
object. Cancelling or failing half way therefore changes nothing. What a bake leaves behind
plays without the extension:

- meshes: the reference key "Basis" holds the rest shape, and each baked frame ``f`` a shape
  key ``sd_bake_<f>`` holding that frame's positions, keyed 0 / 1 / 0 at ``f - step``, ``f``,
  ``f + step`` (linear; the first key has no 0 before it, the last none after it); glTF and
  FBX export them as morph targets.
- curves: F-curves on every control point's ``co`` (and on Bezier points' ``handle_left`` and
  ``handle_right``), one key per baked frame.
- grease pencil: a GP keyframe (its own drawing) per baked frame on every rigged layer, where
  that layer shows the rig's drawing: from its keyframe up to the animator's next one.

One rule outside the baked range, for every kind: the object holds the nearest baked frame (the
first before the range, the last after it), as keyed animation holds its first and last key.
A grease-pencil layer shows nothing before its first keyframe, and a bake adds no drawing
there: the rig's own drawing holds the first baked frame from its keyframe on.

Baking again removes what the previous bake made (recognised by name, by the
``shapedeform_bake`` marks and by the GP keyframes listed on the object, never a drawing a rig
is bound to) before writing, so it replaces and never duplicates.

A baked object is marked (``obj.shapedeform["baked"] = [start, end, step]``) and the live rig
leaves it alone: the bake is what plays (a mesh with shape keys would not show the rig's writes
anyway, and a grease-pencil rig's own drawing must keep its baked frame's pose).
:func:`clear` removes the bake and the mark, and the rig is live again.
"""

import bpy
import numpy as np
from bpy.props import IntProperty

from . import compat, rig
from .sources import RigError, grease_pencil, with_article

PREFIX = "sd_bake_"
MARK = "shapedeform_bake"  # ID property on the data-blocks a bake created
BAKED = "baked"  # on obj.shapedeform: [start, end, step] of the bake; the live rig then rests
GP_FRAMES = "baked_gp_frames"  # on obj.shapedeform: {layer name: [GP keyframes the bake made]}
REST_ATTRIBUTE = "sd_rest"
_LINEAR = 1  # Keyframe.interpolation 'LINEAR' as foreach_set takes it (the enum's value)


def key_name(frame):
    return f"{PREFIX}{frame:04d}"


# -- capturing a frame ------------------------------------------------------------------------

def _capture_mesh(obj, posed):
    mesh = obj.data
    flat = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.attributes["position"].data.foreach_get("vector", flat)
    return flat


def _curve_channels(curve):
    """(data path, width, collection, property) of every animatable point array of a curve."""
    channels = []
    for s, spline in enumerate(curve.splines):
        if spline.type == "BEZIER":
            for prop in ("co", "handle_left", "handle_right"):
                channels.append((f"splines[{s}].bezier_points", 3, spline.bezier_points, prop))
        else:
            channels.append((f"splines[{s}].points", 4, spline.points, "co"))
    return channels


def _capture_curve(obj, posed):
    arrays = []
    for _, width, points, prop in _curve_channels(obj.data):
        flat = np.empty(len(points) * width, dtype=np.float32)
        points.foreach_get(prop, flat)
        arrays.append(flat)
    return arrays


def _capture_grease_pencil(obj, posed):
    """The points the rig wrote into its drawings, all layers together (p, 3) float32."""
    return posed.points(posed.posed)


# An image plane's rig is its cut-out mesh: it bakes to shape keys like any mesh.
_CAPTURE = {"MESH": _capture_mesh, "IMAGE": _capture_mesh, "CURVE": _capture_curve,
            "GREASEPENCIL": _capture_grease_pencil}


# -- writing keys -----------------------------------------------------------------------------

def _channelbag(owner, id_type, name):
    """The channelbag of ``owner``'s action for its slot, made when missing (Blender 4.4+ API)."""
    animation = owner.animation_data or owner.animation_data_create()
    action = animation.action
    if action is None:
        action = bpy.data.actions.new(name)
        action[MARK] = True
        animation.action = action
    slot = animation.action_slot or action.slots.new(id_type=id_type, name=owner.name)
    animation.action_slot = slot
    return compat.ensure_channelbag(action, slot)


def _existing_channelbag(owner):
    animation = owner.animation_data
    if animation is None or animation.action is None or animation.action_slot is None:
        return None
    return compat.channelbag(animation.action, animation.action_slot)


def _add_fcurve(bag, path, index, frames, values):
    """One F-curve with a key per frame, written in bulk and interpolated linearly."""
    curve = bag.fcurves.new(path, index=index)
    points = curve.keyframe_points
    points.add(len(frames))
    points.foreach_set("co", np.column_stack([frames, values]).astype(np.float32).ravel())
    points.foreach_set("interpolation", np.full(len(frames), _LINEAR, dtype=np.int32))
    # Hold the first and last key outside them (Blender's default, stated: the bake's rule).
    curve.extrapolation = "CONSTANT"
    curve.update()
    return curve


def _clear_mesh(obj):
    key = obj.data.shape_keys
    if key is None:
        return 0
    bag = _existing_channelbag(key)
    if bag is not None:
        for curve in [c for c in bag.fcurves if c.data_path.startswith(f'key_blocks["{PREFIX}')]:
            bag.fcurves.remove(curve)
    removed = 0
    for block in [b for b in key.key_blocks if b.name.startswith(PREFIX)]:
        obj.shape_key_remove(block)
        removed += 1
    key = obj.data.shape_keys
    if key is not None and key.get(MARK) and len(key.key_blocks) <= 1:
        # Only the Basis this extension made is left: drop it so the live rig shows again.
        action = key.animation_data.action if key.animation_data else None
        obj.shape_key_clear()
        if action is not None and action.get(MARK) and action.users == 0:
            bpy.data.actions.remove(action)
    return removed


def _write_mesh(obj, frames, captured, step, plan=None):
    if obj.data.shape_keys is None:
        basis = obj.shape_key_add(name="Basis", from_mix=False)
        # The reference key is the rest shape, so a baked key shows exactly its positions.
        basis.data.foreach_set("co", rig.get(obj).source.read_rest(obj).astype(np.float32).ravel())
        obj.data.shape_keys[MARK] = True
    key = obj.data.shape_keys
    bag = _channelbag(key, "KEY", f"{obj.name} Shape Deform Bake")
    for i, (frame, flat) in enumerate(zip(frames, captured)):
        block = obj.shape_key_add(name=key_name(frame), from_mix=False)
        block.data.foreach_set("co", flat)
        path = f'key_blocks["{bpy.utils.escape_identifier(block.name)}"].value'
        # Faded in from the frame before and out to the frame after; the first key has no
        # fade-in and the last no fade-out, so they hold (constant extrapolation) outside the
        # range, as every kind does.
        keys = ([(frames[i - 1], 0.0)] if i > 0 else []) + [(frame, 1.0)] + \
            ([(frames[i + 1], 0.0)] if i + 1 < len(frames) else [])
        _add_fcurve(bag, path, 0, *zip(*keys))


def _clear_curve(obj):
    bag = _existing_channelbag(obj.data)
    if bag is None:
        return 0
    baked = [c for c in bag.fcurves if c.data_path.startswith("splines[")]
    for curve in baked:
        bag.fcurves.remove(curve)
    return len(baked)


def _write_curve(obj, frames, captured, step, plan=None):
    bag = _channelbag(obj.data, "CURVE", f"{obj.name} Shape Deform Bake")
    frames = np.asarray(frames, dtype=np.float32)
    for c, (path, width, points, prop) in enumerate(_curve_channels(obj.data)):
        values = np.stack([arrays[c] for arrays in captured]).reshape(len(frames), len(points), width)
        for i in range(len(points)):
            for axis in range(3):  # x, y, z (a NURBS weight is never deformed)
                _add_fcurve(bag, f"{path}[{i}].{prop}", axis, frames, values[:, i, axis])


def _made_frames(obj):
    """{layer name: frame numbers} of the GP keyframes earlier bakes made that a clear removes.

    Never a drawing the rig is bound to: a file saved before Unbind cleared bakes can list one
    (bake, unbind, bind on a baked frame), and removing it would destroy the rig's own drawing.
    """
    made = obj.shapedeform.get(GP_FRAMES)
    made = made.to_dict() if made is not None else {}
    bound = set(grease_pencil.bound_frames(obj))
    return {name: {int(n) for n in numbers if (name, int(n)) not in bound} for name, numbers in made.items()}


def _clear_grease_pencil(obj):
    removed = 0
    for name, numbers in _made_frames(obj).items():
        layer = obj.data.layers.get(name)
        if layer is None:
            continue
        existing = {f.frame_number for f in layer.frames}
        for number in numbers & existing:
            layer.frames.remove(number)
            removed += 1
    obj.shapedeform.pop(GP_FRAMES, None)
    return removed


def _set_positions(drawing, flat):
    drawing.attributes["position"].data.foreach_set("vector", np.ascontiguousarray(flat).ravel())
    drawing.tag_positions_changed()


def _plan_grease_pencil(obj, frames, captured):
    """Each rigged layer's (name, bound frame, first point, point count, frames it keeps).

    Looked up before the clear, from what the clear leaves, so a drawing that is missing stops
    the bake before anything was removed.
    """
    made = _made_frames(obj)
    numbers = np.asarray(frames)
    plan, start = [], 0
    for name, bound in grease_pencil.bound_frames(obj):
        drawing = grease_pencil.drawing_at(obj, name, bound)
        if drawing is None:
            raise RigError(f"'{obj.name}' lost the drawing of layer '{name}' at frame {bound}; unbind it")
        count = len(drawing.attributes["position"].data)
        # The animator's own keyframes (not made by a bake) are not the rig's: they stay, and
        # the rig's drawing shows from its own frame up to the next of them. Only there does the
        # bake add drawings: never before the layer's first keyframe, never over theirs.
        kept = {f.frame_number for f in obj.data.layers[name].frames} - made.get(name, set())
        until = min((n for n in kept if n > bound), default=None)
        shown = np.flatnonzero((numbers > bound) & ((numbers < until) if until is not None else True))
        # The rig's drawing itself holds the nearest baked frame at or before its own (the
        # first baked frame when the range starts after it), as every baked keyframe holds.
        hold = max(int(np.searchsorted(numbers, bound, side="right")) - 1, 0)
        plan.append((name, bound, start, count, hold, shown))
        start += count
    if any(len(points) != start for points in captured):
        raise RigError(f"'{obj.name}' changed its strokes during the bake")
    return plan


def _write_grease_pencil(obj, frames, captured, step, plan):
    made = {}
    for name, bound, start, count, hold, shown in plan:
        layer = obj.data.layers[name]
        # The live rig leaves a baked object alone, so the rig's drawing keeps this pose.
        _set_positions(grease_pencil.drawing_at(obj, name, bound), captured[hold][start:start + count])
        made[name] = []
        for i in shown:
            new = layer.frames.copy(bound, frames[i], instance_drawing=False)
            drawing = new.drawing  # at once: adding frames can move the others in memory
            if REST_ATTRIBUTE in drawing.attributes:  # the copy needs no rest of its own
                drawing.attributes.remove(drawing.attributes[REST_ATTRIBUTE])
            _set_positions(drawing, captured[i][start:start + count])
            made[name].append(int(frames[i]))
    obj.shapedeform[GP_FRAMES] = made
    obj.data.update_tag()


def _plan_mesh(obj, frames, captured):
    if any(len(flat) != 3 * len(obj.data.vertices) for flat in captured):
        raise RigError(f"'{obj.name}' changed its vertex count during the bake")


def _plan_curve(obj, frames, captured):
    sizes = [len(points) * width for _, width, points, _ in _curve_channels(obj.data)]
    if any([len(a) for a in arrays] != sizes for arrays in captured):
        raise RigError(f"'{obj.name}' changed its control points during the bake")


# Per kind: clear the previous bake; plan the write (RigError when it cannot be done, nothing
# changed yet); write.
_WRITE = {"MESH": (_clear_mesh, _plan_mesh, _write_mesh), "IMAGE": (_clear_mesh, _plan_mesh, _write_mesh),
          "CURVE": (_clear_curve, _plan_curve, _write_curve),
          "GREASEPENCIL": (_clear_grease_pencil, _plan_grease_pencil, _write_grease_pencil)}


def is_baked(obj):
    """Whether ``obj`` plays a bake (the live rig then leaves it alone until the bake is cleared)."""
    return BAKED in obj.shapedeform


def clear(obj):
    """Remove what earlier bakes made on ``obj``; returns how many keys/frames were removed."""
    kind = obj.shapedeform.kind
    obj.shapedeform.pop(BAKED, None)
    if kind not in _WRITE:
        return 0
    return _WRITE[kind][0](obj)


# -- the bake ---------------------------------------------------------------------------------

def frame_list(frame_start, frame_end, step=1):
    """The frames a bake poses; ValueError naming the problem for a bad range."""
    frame_start, frame_end, step = int(frame_start), int(frame_end), int(step)
    if step < 1:
        raise ValueError(f"the frame step must be 1 or more, got {step}")
    if frame_end < frame_start:
        raise ValueError(f"the last frame ({frame_end}) comes before the first ({frame_start})")
    return list(range(frame_start, frame_end + 1, step))


class Bake:
    """A bake in progress, one frame per :meth:`step`, written by :meth:`finish`.

    Parameters
    ----------
    objects : iterable of bpy.types.Object
        Bound objects with handles.
    frames : list of int
        See :func:`frame_list`.
    step : int
        Frame step (sets where a mesh's shape key fades in and out).
    scene : bpy.types.Scene, optional

    Raises
    ------
    RigError
        An object is not bound, has no handles, or is of a kind that cannot be baked.
    """

    def __init__(self, objects, frames, step=1, scene=None):
        self.scene = scene or bpy.context.scene
        self.objects = list(objects)
        if not self.objects:
            raise RigError("Nothing to bake: no bound objects were given")
        for obj in self.objects:
            settings = obj.shapedeform
            if not settings.is_bound:
                raise RigError(f"'{obj.name}' is not bound: nothing to bake")
            if settings.kind not in _WRITE:
                raise RigError(f"'{obj.name}' is {with_article(settings.kind.lower() or 'unknown')} rig, "
                               "which cannot be baked yet")
            if not any(item.object is not None for item in settings.handles):
                raise RigError(f"'{obj.name}' has no handles: nothing moves, nothing to bake")
        self.frames = list(frames)
        if not self.frames:
            raise RigError("Nothing to bake: the frame range is empty")
        self.step_size = int(step)
        self.captured = {obj.name: [] for obj in self.objects}
        self.done = 0
        self.original_frame = (self.scene.frame_current, self.scene.frame_subframe)

    @property
    def total(self):
        return len(self.frames)

    def step(self):
        """Pose the next frame and keep its positions; returns True when every frame is done.

        Raises
        ------
        RigError
            A frame could not be posed (the message names the object); call :meth:`abort`.
        """
        frame = self.frames[self.done]
        self.scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for obj in self.objects:
            posed = rig.pose(obj, depsgraph, final=True)  # explicitly: a bake does not rely on the handlers
            self.captured[obj.name].append(_CAPTURE[obj.shapedeform.kind](obj, posed))
        self.done += 1
        return self.done == self.total

    def _restore_frame(self):
        self.scene.frame_set(self.original_frame[0], subframe=self.original_frame[1])

    def abort(self):
        """Stop without writing anything; the scene goes back to its frame and live pose."""
        self.captured.clear()
        self._restore_frame()

    def finish(self):
        """Replace each object's previous bake with this one; returns the objects baked.

        Every object's write is planned (and refused) before any previous bake is cleared, so
        a bake that cannot be written changes nothing.

        Raises
        ------
        RigError
            An object cannot take the bake (e.g. its grease-pencil drawing is gone); nothing
            was changed (call :meth:`abort`).
        """
        self._restore_frame()
        plans = [_WRITE[obj.shapedeform.kind][1](obj, self.frames, self.captured[obj.name])
                 for obj in self.objects]
        for obj, plan in zip(self.objects, plans):
            clear_bake, _, write = _WRITE[obj.shapedeform.kind]
            clear_bake(obj)
            write(obj, self.frames, self.captured[obj.name], self.step_size, plan)
            obj.shapedeform[BAKED] = [self.frames[0], self.frames[-1], self.step_size]
        self.captured.clear()
        self._restore_frame()  # show the baked result at the current frame
        return self.objects


def bake_objects(objects, frame_start, frame_end, step=1, *, scene=None, progress=None, cancelled=None):
    """Bake the live deformation of ``objects`` into keyframes; the Python entry point.

    Parameters
    ----------
    objects : iterable of bpy.types.Object
        Bound objects with handles.
    frame_start, frame_end : int
        First and last frame, both baked.
    step : int
        Bake every ``step``-th frame.
    scene : bpy.types.Scene, optional
        Defaults to the context's scene.
    progress : callable(done, total), optional
        Called after each frame.
    cancelled : callable() -> bool, optional
        Polled after each frame; when it returns True the bake stops and nothing is written.

    Returns
    -------
    list of bpy.types.Object or None
        The baked objects; None when cancelled.

    Raises
    ------
    ValueError
        A bad frame range or step.
    RigError
        An object cannot be baked, or a frame could not be posed; nothing was written.
    """
    baker = Bake(objects, frame_list(frame_start, frame_end, step), step, scene)
    try:
        finished = False
        while not finished:
            finished = baker.step()
            if progress is not None:
                progress(baker.done, baker.total)
            if not finished and cancelled is not None and cancelled():
                baker.abort()
                return None
        return baker.finish()
    except BaseException:
        baker.abort()
        raise


# -- operator ---------------------------------------------------------------------------------

def _targets(context):
    """Selected bound objects, plus the rig of the active object or of an active handle."""
    from .drag import rig_object

    found = [o for o in context.selected_objects if o.shapedeform.is_bound]
    active = rig_object(context)
    if active is not None and active not in found:
        found.append(active)
    return found


class SHAPEDEFORM_OT_bake(bpy.types.Operator):
    """Bake the selected rigs' deformation into keyframes that play without the extension"""

    bl_idname = "shapedeform.bake"
    bl_label = "Bake Deformation"
    bl_options = {"REGISTER", "UNDO"}

    frame_start: IntProperty(name="Start", description="First frame to bake", default=1)
    frame_end: IntProperty(name="End", description="Last frame to bake", default=250)
    step: IntProperty(name="Step", description="Bake every n-th frame", default=1, min=1)

    def _start(self, context):
        if not self.properties.is_property_set("frame_start"):
            self.frame_start = context.scene.frame_start
        if not self.properties.is_property_set("frame_end"):
            self.frame_end = context.scene.frame_end
        try:
            return Bake(_targets(context), frame_list(self.frame_start, self.frame_end, self.step),
                        self.step, context.scene)
        except (RigError, ValueError) as err:
            self.report({"ERROR"}, str(err))
            return None

    def execute(self, context):
        baker = self._start(context)
        if baker is None:
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, baker.total)
        try:
            finished = False
            while not finished:
                finished = baker.step()
                wm.progress_update(baker.done)
            baker.finish()
        except RigError as err:
            baker.abort()
            self.report({"ERROR"}, f"Bake stopped, nothing was changed: {err}")
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        self.report({"INFO"}, f"Baked {baker.total} frames of {len(baker.objects)} object(s)")
        return {"FINISHED"}

    def invoke(self, context, event):
        # Modal, one frame per timer tick, so Esc can cancel and the progress bar moves.
        self.baker = self._start(context)
        if self.baker is None:
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, self.baker.total)
        self.timer = wm.event_timer_add(0.001, window=context.window)
        wm.modal_handler_add(self)
        context.workspace.status_text_set("Baking deformation: Esc cancels (nothing is changed)")
        return {"RUNNING_MODAL"}

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self.timer)
        wm.progress_end()
        context.workspace.status_text_set(None)

    def modal(self, context, event):
        if event.type == "ESC":
            self.baker.abort()
            self._end(context)
            self.report({"WARNING"}, "Bake cancelled: nothing was changed")
            return {"CANCELLED"}
        if event.type != "TIMER" or event.timer is not self.timer:
            return {"RUNNING_MODAL"}
        try:
            finished = self.baker.step()
            context.window_manager.progress_update(self.baker.done)
            if finished:
                self.baker.finish()
        except RigError as err:
            self.baker.abort()
            self._end(context)
            self.report({"ERROR"}, f"Bake stopped, nothing was changed: {err}")
            return {"CANCELLED"}
        if not finished:
            return {"RUNNING_MODAL"}
        self._end(context)
        self.report({"INFO"}, f"Baked {self.baker.total} frames of {len(self.baker.objects)} object(s)")
        return {"FINISHED"}


class SHAPEDEFORM_OT_clear_bake(bpy.types.Operator):
    """Remove the keys a bake made on the selected rigs, so the live rig shows again"""

    bl_idname = "shapedeform.clear_bake"
    bl_label = "Clear Bake"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        targets = _targets(context)
        if not targets:
            self.report({"ERROR"}, "Select bound objects to clear their bake")
            return {"CANCELLED"}
        for obj in targets:
            clear(obj)
            rig.pose_safely(obj, context.evaluated_depsgraph_get())
        return {"FINISHED"}


classes = (SHAPEDEFORM_OT_bake, SHAPEDEFORM_OT_clear_bake)

register, unregister = bpy.utils.register_classes_factory(classes)
