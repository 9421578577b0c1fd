# SPDX-License-Identifier: GPL-3.0-or-later
"""Baking: the rig's motion turned into ordinary Blender animation, the same for every kind.

A bake poses every frame of a range (the frame's pose depends only on the handles at that
frame, so the order does not matter), keeps the cage's points in memory, and only when every
frame is done replaces the previous bake. Cancelling or failing half way therefore changes
nothing. What it leaves is shape keys on the cage's mesh: the reference key "Basis" holds the
rest, and each baked frame ``f`` a key ``sd_bake_<f>`` holding that frame's pose. The keys are
absolute (not *Relative*): each sits at its own place in the Key's *Evaluation Time*, and one
F-curve on that time, keyed linearly at the animation time each baked frame shows (which Time
Stretching changes), plays them in turn. Relative keys would need an F-curve per frame, which
Blender evaluates, looking each up by name, on every frame change: 500 baked frames cost 8-11 ms
per frame change that way, 2,000 frames 130 ms (``benchmarks/playback.py --bake-frames``). The
object's Shape Deform modifier maps its points through the cage whatever moves the cage, so a
baked file plays and renders with the extension disabled, and every kind of object (a
grease-pencil drawing the animator adds later too) plays the same bake. Bakes made before
(relative keys keyed 0 / 1 / 0) play, show live and clear as they did.

Outside the baked range the cage holds the nearest baked frame (the first before the range, the
last after it), as keyed animation holds its first and last key.

A baked rig is marked (``obj.shapedeform["baked"] = [start, end, step]``) and the live rig
leaves its cage alone: the bake is what plays. :func:`clear` removes the bake and the mark, and
the rig is live again.

A bake keeps a digest of what it was made from, on its Key (:mod:`.bake_source`): once the
handles' keys or transforms, the pins or the rig's settings change, the sidebar says it is out
of date, as Blender's physics caches flag themselves outdated.
"""

import bpy
import numpy as np
from bpy.props import BoolProperty, IntProperty

from ..solver.wording import by_count
from . import bake_source, compat, handlers, rig, rig_format
from .errors import RigError, poll_reason

PREFIX = "sd_bake_"
MARK = rig_format.BAKE_MARK
IN_TIME = rig_format.BAKE_IN_TIME
BAKED = rig_format.BAKED
FRAMES = rig_format.BAKE_FRAMES
_LINEAR = 1  # Keyframe.interpolation 'LINEAR' as foreach_set takes it (the enum's value)


def key_name(frame):
    """The name of the shape key a bake writes for ``frame``."""
    return f"{PREFIX}{frame:04d}"


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


def _add_fcurve(bag, path, frames, values):
    """One F-curve with a key per frame, written in bulk and interpolated linearly."""
    curve = bag.fcurves.new(path, index=0)
    points = curve.keyframe_points
    points.add(len(frames))
    points.foreach_set("co", np.column_stack([frames, values]).astype(np.float32).ravel())
    points.foreach_set("interpolation", np.full(len(frames), _LINEAR, dtype=np.int32))
    # Hold the first and last key outside them (Blender's default, stated: the bake's rule).
    curve.extrapolation = "CONSTANT"
    curve.update()
    return curve


def _remove_keys(cage):
    key = cage.data.shape_keys
    if key is None:
        return 0
    animation = key.animation_data
    # Pushed down (or stashed), the bake's action is a strip's, no longer the active one.
    actions = [action for action, _ in compat.played_actions(animation)]
    removed = sum(1 for b in key.key_blocks if b.name.startswith(PREFIX))
    uid = key.session_uid
    cage.shape_key_clear()
    # Blender 4.5 and 5.0 give a copied mesh's shape keys one user too many (a duplicate's own
    # cage is such a copy): clearing them then leaves the Key behind, pointing at nothing, and
    # every later save reports it.
    left = [k for k in bpy.data.shape_keys if k.session_uid == uid]
    if left:
        bpy.data.batch_remove(left)
    bpy.data.batch_remove({action for action in actions
                           if action is not None and action.get(MARK) and action.users == 0})
    return removed


def _show_live(cage, points):
    """Have a baked cage show ``points`` (n, 3) instead of its bake (whose keys are muted and made
    relative, the pose put in its reference key), or, with None, play its bake again."""
    key = cage.data.shape_keys if cage is not None else None
    if key is None:  # the cage changed under the bake (which then fails): nothing to show
        return
    for block in key.key_blocks:
        if block.name.startswith(PREFIX):
            block.mute = points is not None
    key.use_relative = points is not None or not key.get(IN_TIME)
    shown = rig_format.rest_of(cage) if points is None else np.ascontiguousarray(points, dtype=np.float32)
    key.reference_key.data.foreach_set("co", shown.ravel())
    cage.data.update()


def _write_keys(cage, frames, step, captured, times):
    """Keep each captured pose in a shape key, played at the animation time its frame showed
    (``times``, the scene's ``frame_current_final``): playback maps a frame to its time for
    these keys as for the handles', so with Time Stretching a key at the frame itself would be
    stretched twice."""
    basis = cage.shape_key_add(name="Basis", from_mix=False)
    # The reference key is the rest, as in the relative bakes of earlier versions.
    basis.data.foreach_set("co", rig_format.rest_of(cage).ravel())
    key = cage.data.shape_keys
    key[MARK] = key[IN_TIME] = True
    key[FRAMES] = [frames[0], frames[-1], step]
    key.use_relative = False
    key_times = rig_format.bake_key_times(len(frames))
    # An absolute Key puts a new key where its time is (Blender divides the time by 100 for the
    # key's place as it does when playing, so at that time the key shows alone, exactly), unless
    # a tenth after the last key is within 0.001 of that place: added from the last, none is.
    for frame, points, key_time in reversed(list(zip(frames, captured, key_times))):
        key.eval_time = float(key_time)
        cage.shape_key_add(name=key_name(frame), from_mix=False).data.foreach_set("co", points.ravel())
    key.eval_time = float(key_times[0])
    bag = _channelbag(key, "KEY", rig_format.bake_action_name(cage))
    _add_fcurve(bag, "eval_time", times, key_times)


def baked_frames(obj):
    """(first frame, last frame, step) of the bake owner ``obj`` plays; None when it plays none,
    or one whose frames are not known.

    Read from the bake's Key, which a library override keeps with its local cage: the owner's
    mark comes back from the library on reopening (QA: Bake Again then baked the library's
    frames, or the preview range's)."""
    cage = obj.shapedeform.cage
    key = cage.data.shape_keys if cage is not None and cage.data is not None else None
    mark = key.get(FRAMES) if key is not None else None
    if mark is None and rig_format.is_baked(obj):  # a bake from before the Key held them
        mark = obj.shapedeform.get(BAKED)
    return tuple(int(value) for value in mark) if mark is not None and len(mark) == 3 else None


def played_frames(obj, scene):
    """(first, last) frames of ``scene`` between which the bake ``obj`` plays moves, as its keys
    are now (retimed too); None when it is not baked, or played through NLA strips (their own
    timing is not read)."""
    frames = baked_frames(obj)
    key = obj.shapedeform.cage.data.shape_keys if frames is not None and obj.shapedeform.cage else None
    if key is None or not key.get(IN_TIME):  # an earlier version's bake, keyed per frame
        return frames[:2] if frames is not None else None
    animation = key.animation_data
    bag = compat.channelbag(animation.action, animation.action_slot) \
        if animation is not None and animation.action is not None and not len(animation.nla_tracks) else None
    curve = bag.fcurves.find("eval_time") if bag is not None else None
    if curve is None or not len(curve.keyframe_points):
        return None
    # Keyed at the animation times the frames showed: Time Stretching maps frames to times.
    to_frames = scene.render.frame_map_new / scene.render.frame_map_old
    first, last = curve.keyframe_points[0].co.x, curve.keyframe_points[-1].co.x
    return int(np.ceil(first * to_frames - 1e-4)), int(np.floor(last * to_frames + 1e-4))


def clear(obj):
    """Remove the bake of ``obj``'s rig; returns how many baked frames were removed."""
    owner = rig_format.owner_of(obj)
    if owner is None:
        return 0
    owner.shapedeform.pop(BAKED, None)
    bake_source.forget(owner)
    cage = owner.shapedeform.cage
    if cage is None or rig_format.own_mesh(cage) is None:
        return 0
    return _remove_keys(cage)


# -- the bake ---------------------------------------------------------------------------------

# The frames Blender has: a key past them lands on the last one (a bake that went past wrote
# every later frame's key there, over each other).
FIRST_FRAME = bpy.types.Scene.bl_rna.properties["frame_current"].hard_min
LAST_FRAME = bpy.types.Scene.bl_rna.properties["frame_current"].hard_max


def frames_text(first, last):
    """"frame 5" or "frames 1 to 24": frames may be negative, so no dash between them (QA:
    "frames -5--1")."""
    return f"frame {first}" if first == last else f"frames {first} to {last}"


def check_frames(frame_start, frame_end, step=1):
    """ValueError naming the problem when ``frame_start``-``frame_end`` every ``step`` frames
    is not a range of frames Blender has."""
    if step < 1:
        raise ValueError(f"the frame step must be 1 or more, got {step}")
    if frame_end < frame_start:
        raise ValueError(f"the last frame ({frame_end}) comes before the first ({frame_start})")
    if frame_start < FIRST_FRAME or frame_end > LAST_FRAME:
        runs = "runs" if frame_start == frame_end else "run"
        raise ValueError(f"{frames_text(frame_start, frame_end)} {runs} past Blender's, which go from {FIRST_FRAME} "
                         f"to {LAST_FRAME}")


def frame_list(frame_start, frame_end, step=1):
    """The frames a bake poses: every ``step``-th from the first, and the last (which a step
    that does not land on it would leave holding the pose of the frame before); ValueError
    naming the problem for a bad range."""
    frame_start, frame_end, step = int(frame_start), int(frame_end), int(step)
    check_frames(frame_start, frame_end, step)
    frames = list(range(frame_start, frame_end + 1, step))
    return frames if frames[-1] == frame_end else frames + [frame_end]


def _may_follow_others(obj):
    """Whether a handle of ``obj``'s rig may follow another object's shape: something on its
    way up to the rig (the owner or its cage, a pin's parent) has drivers, a constraint aimed
    at another object, or is not an Empty (a bone, a vertex parent). Handles keyed or moved by
    hand, pins, and a curve's handles following it along its path follow nothing else."""
    own = {obj, obj.shapedeform.cage}
    for item in obj.shapedeform.handles:
        link = item.object
        while link is not None and link not in own:
            drivers = link.animation_data.drivers if link.animation_data is not None else ()
            aimed = [c for c in link.constraints if _objects_read(c) - own]
            if aimed or len(drivers) or link.type != "EMPTY":
                return True
            link = link.parent
    return False


def _objects_read(constraint):
    """The objects ``constraint`` reads: its target, custom space, camera, ..., and each of an
    Armature constraint's targets (a list, which ``target`` alone missed)."""
    found = [getattr(constraint, prop.identifier) for prop in constraint.bl_rna.properties
             if prop.type == "POINTER" and prop.fixed_type.identifier == "Object"]
    found += [target.target for target in getattr(constraint, "targets", ())]
    return {obj for obj in found if obj is not None}


class Bake:
    """A bake in progress, one frame per :meth:`step`, written by :meth:`finish`.

    Parameters
    ----------
    objects : iterable of bpy.types.Object
        Bound objects with handles.
    frames : list of int
        See :func:`frame_list`.
    step : int
        Frame step (recorded in the bake's mark).
    scene : bpy.types.Scene, optional
    own_frames : dict of str to (list of int, int), optional
        Rigs (their owners' names) baked on frames of their own, and their step: Bake Again of
        several rigs bakes each over its previous bake's. Every rig is posed on every frame of
        the bake (a rig's handles may follow another's shape), and keeps its own.

    Raises
    ------
    RigError
        An object is not bound, has no handles, or is not evaluated in the scene's view layer.
    """

    def __init__(self, objects, frames, step=1, scene=None, own_frames=None):
        self.scene = scene or bpy.context.scene
        self.objects = []
        for obj in objects:
            owner = rig_format.owner_of(obj)
            if owner is None:
                raise RigError(f"'{obj.name}' is not bound: nothing to bake")
            if owner not in self.objects:  # a duplicate bakes the rig it follows, once
                self.objects.append(owner)
        if not self.objects:
            raise RigError("Nothing to bake: no bound objects were given")
        for obj in self.objects:
            rig_format.require_posable(obj, "bake it")
            settings = obj.shapedeform
            if settings.cage is None:
                raise RigError(rig.lost_cage(obj))
            if not rig_format.present_items(obj):
                raise RigError(f"'{obj.name}' has no handles: nothing moves, nothing to bake")
            if not rig_format.modifiers_of(obj):
                raise RigError(f"'{obj.name}' lost its Shape Deform modifier (applied, removed, or converted): "
                               "nothing would play the bake; Unbind removes the rig and keeps the shape")
        # Frames are posed from this depsgraph: an object it leaves out would bake stale handles.
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for obj in self.objects:
            if not obj.evaluated_get(depsgraph).is_evaluated:
                raise RigError(f"'{obj.name}' is not evaluated in the view layer '{depsgraph.view_layer.name}' "
                               "(disabled in viewports, or excluded there): enable it, or bake from a view "
                               "layer that shows it")
        own_frames = own_frames or {}
        self.frames_of = {obj.name: own_frames.get(obj.name, (list(frames), int(step))) for obj in self.objects}
        self.frames = sorted({frame for wanted, _ in self.frames_of.values() for frame in wanted})
        if not self.frames:
            raise RigError("Nothing to bake: the frame range is empty")
        self.keeps = {name: set(wanted) for name, (wanted, _) in self.frames_of.items()}
        # The live rigs this bake leaves live: the paused handlers do not pose them, so the bake
        # does, on every frame, where a baked rig's handles may follow their shapes.
        self.live = [obj for obj in rig_format.owners(self.scene, depsgraph) if obj not in self.objects
                     and obj.shapedeform.handles and not rig_format.is_baked(obj)
                     ] if any(_may_follow_others(obj) for obj in self.objects) else []
        # Rigs baked before: their cages play that bake, which the rigs following them would
        # read; for the length of this bake they show what it solves (:func:`_show_live`).
        self.rebaked = [obj for obj in self.objects if rig_format.is_baked(obj)]
        self.captured = {obj.name: [] for obj in self.objects}
        self.times = {obj.name: [] for obj in self.objects}  # the animation time each kept frame showed
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
            A frame could not be posed (the message names it and the object); call :meth:`abort`.
        """
        frame = self.frames[self.done]
        try:
            self._pose_frame(frame)
        except RigError as err:
            raise RigError(f"frame {frame}: {err}") from None
        self.done += 1
        return self.done == self.total

    def _pose_frame(self, frame):
        with handlers.paused():
            self.scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        posed = {}  # not via the handlers
        chain = [obj for obj in self.objects + self.live if self._pose(obj, depsgraph, posed)]
        # A rig whose handles follow another rig's shape (a hat pinned to a deformed head) sees
        # that shape's new pose only once the depsgraph has evaluated it: evaluate, and pose again
        # the rigs whose handles moved, once per link of such a chain.
        for _ in range(len(chain) - 1):
            before = {obj.name: rig.handle_frames(obj, depsgraph) for obj in chain}
            with handlers.paused():
                depsgraph.update()
            moved = [obj for obj in chain if not np.array_equal(rig.handle_frames(obj, depsgraph), before[obj.name])]
            if not moved:
                break
            chain = [obj for obj in chain if obj not in moved or self._pose(obj, depsgraph, posed)]
        for obj in self.objects:
            if frame in self.keeps[obj.name]:
                self.captured[obj.name].append(posed[obj.name])
                self.times[obj.name].append(self.scene.frame_current_final)

    def _pose(self, obj, depsgraph, posed):
        """Pose ``obj``'s rig at this frame, keeping a baked rig's pose in ``posed``; False when
        a live rig failed (it keeps its last pose and says why in its status, as in playback,
        and the bake goes on without it)."""
        if obj in self.objects:
            posed[obj.name] = rig.pose(obj, depsgraph, final=True).shown
            if obj in self.rebaked:
                _show_live(obj.shapedeform.cage, posed[obj.name])
            return True
        return not rig.pose_safely(obj, depsgraph, final=True)

    def summary(self):
        """What a finished bake did, for the status bar ("Baked 24 frames of 1 object")."""
        frames, objects = self.total, len(self.objects)
        return (f"Baked {frames} {by_count(frames, 'frame', 'frames')} of {objects} "
                f"{by_count(objects, 'object', 'objects')}")

    def _restore_frame(self):
        self.scene.frame_set(self.original_frame[0], subframe=self.original_frame[1])

    def abort(self):
        """Stop without writing anything; the scene goes back to its frame and live pose (a
        rig baked before, to its bake)."""
        self.captured.clear()
        for obj in self.rebaked:
            _show_live(obj.shapedeform.cage, None)
        self._restore_frame()

    def finish(self):
        """Replace each rig's previous bake with this one; returns the rig owners baked.

        Raises
        ------
        RigError
            A rig lost its cage during the bake; nothing was changed (call :meth:`abort`).
        """
        self._restore_frame()
        for obj in self.objects:
            cage = obj.shapedeform.cage
            if cage is None or any(len(p) != len(cage.data.vertices) for p in self.captured[obj.name]):
                raise RigError(f"'{obj.name}' lost or changed its cage during the bake")
        for obj in self.objects:
            clear(obj)
            frames, step = self.frames_of[obj.name]
            _write_keys(obj.shapedeform.cage, frames, step, self.captured[obj.name], self.times[obj.name])
            obj.shapedeform[BAKED] = [frames[0], frames[-1], step]  # what earlier versions read
            rig_format.store_bake_source(obj.shapedeform.cage, *bake_source.fingerprint(obj))
            bake_source.forget(obj)
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
        Bake every ``step``-th frame from ``frame_start``, and ``frame_end``.
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
    if scene is not None and scene != bpy.context.scene:
        # Frames are posed from the context's depsgraph: make it the scene's.
        with bpy.context.temp_override(scene=scene):
            return bake_objects(objects, frame_start, frame_end, step, progress=progress, cancelled=cancelled)
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

def _frames_by_default(scene):
    """The first and last frame a bake from the interface covers when none are given: the
    scene's preview range while it is on, as Blender's Bake Action takes it (the animator is
    working on those frames), else its frame range."""
    if scene.use_preview_range:
        return scene.frame_preview_start, scene.frame_preview_end
    return scene.frame_start, scene.frame_end


def _targets(context):
    """Selected bound objects, plus the rig of the active object or of an active handle."""
    found = []
    for obj in list(context.selected_objects) + [context.active_object]:
        owner = rig_format.owner_of(obj)
        if owner is not None and owner not in found:
            found.append(owner)
    return found


class SHAPEDEFORM_OT_bake(bpy.types.Operator):
    """Bake the deformation of the selected rigs and the active one into keyframes that play without the extension"""

    bl_idname = "shapedeform.bake"
    bl_label = "Bake Deformation"
    bl_options = {"REGISTER", "UNDO"}

    # Not remembered between bakes: unset, they are the scene's at the time (its preview range
    # while on: _frames_by_default). Soft limits only: a hard one would clamp a range past
    # Blender's frames and bake what is left without a word; execute refuses it by name.
    frame_start: IntProperty(name="Start", description="First frame to bake (default: the scene's, or its preview "
                                                       "range's while that is on)", default=1,
                             soft_min=FIRST_FRAME, soft_max=LAST_FRAME, options={"SKIP_SAVE"})
    frame_end: IntProperty(name="End", description="Last frame to bake (default: the scene's, or its preview "
                                                   "range's while that is on)", default=250,
                           soft_min=FIRST_FRAME, soft_max=LAST_FRAME, options={"SKIP_SAVE"})
    step: IntProperty(name="Step", description="Bake every n-th frame", default=1, min=1)
    again: BoolProperty(name="Again", description="Bake each rig baked before over the frames and step of its "
                                                  "bake (the others over Start, End and Step)",
                        default=False, options={"SKIP_SAVE"})

    @classmethod
    def poll(cls, context):
        return poll_reason(cls, "" if _targets(context) else "Select bound objects to bake their deformation")

    def _start(self, context):
        frame_start, frame_end = _frames_by_default(context.scene)
        if not self.properties.is_property_set("frame_start"):
            self.frame_start = frame_start
        if not self.properties.is_property_set("frame_end"):
            self.frame_end = frame_end
        targets = _targets(context)
        try:
            own = {obj.name: (frame_list(*frames), frames[2]) for obj in targets
                   if self.again and (frames := baked_frames(obj)) is not None}
            return Bake(targets, frame_list(self.frame_start, self.frame_end, self.step),
                        self.step, context.scene, own_frames=own)
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
        except Exception:
            baker.abort()  # a failure nobody foresaw still leaves the scene as it was
            raise
        finally:
            wm.progress_end()
        self.report({"INFO"}, baker.summary())
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
        except Exception:
            self.baker.abort()
            self._end(context)
            raise
        if not finished:
            return {"RUNNING_MODAL"}
        self._end(context)
        self.report({"INFO"}, self.baker.summary())
        return {"FINISHED"}


class SHAPEDEFORM_OT_clear_bake(bpy.types.Operator):
    """Remove the keys a bake made on the selected rigs and the active one, so the live rig shows again"""

    bl_idname = "shapedeform.clear_bake"
    bl_label = "Clear Bake"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_reason(cls, "" if _targets(context) else "Select bound objects to clear their bake")

    def execute(self, context):
        targets = _targets(context)
        if not targets:
            self.report({"ERROR"}, "Select bound objects to clear their bake")
            return {"CANCELLED"}
        try:
            for obj in targets:
                rig_format.require_posable(obj, "clear its bake")
        except RigError as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        for obj in targets:
            clear(obj)
            rig.pose_safely(obj, context.evaluated_depsgraph_get())
        return {"FINISHED"}


classes = (SHAPEDEFORM_OT_bake, SHAPEDEFORM_OT_clear_bake)

register, unregister = bpy.utils.register_classes_factory(classes)
