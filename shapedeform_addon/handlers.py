# SPDX-License-Identifier: GPL-3.0-or-later
"""App handlers that keep rigs live: handle moves, frame changes, file loads and undo.

While the animator drags, plays or scrubs, solves have the Viewport iteration budget; one that
stops short of converging leaves a pose a render (Render budget) would not give. A one-shot
timer then solves those rigs again with the Render budget once the updates pause, so what stays
on screen is what renders, as Blender's viewport refines its samples when the view stops
changing. A frame stepped to is solved with the Render budget at once. Another timer binds pins
moved by hand to the points they are left on once the move is over.
"""

import sys
import traceback
from contextlib import contextmanager

import bpy
from bpy.app.handlers import persistent

from . import duplicates, handles, nodes, rig, rig_format
from .errors import RigError
from .sources import grease_pencil, mesh

# Writing geometry makes Blender evaluate again and call us back: ignore those calls.
_busy = False


@contextmanager
def paused():
    """Leave rigs alone while the caller poses them itself: the handlers' own writes call them
    back, and a bake steps through frames solving each once, with the Render budget."""
    global _busy
    was, _busy = _busy, True
    try:
        yield
    finally:
        _busy = was


# The status bar shows our text until we clear it: what we last showed ("" for nothing).
_status_text = ""


def _report(messages):
    """Show why updates failed in the status bar, or, once they work again, clear what an
    earlier failure showed (and nothing else's text). While any failure shows, the text is
    every failing rig's of the scene (each owner keeps its reason in ``shapedeform.status``),
    so a rig that works does not hide another that still fails."""
    global _status_text
    if not any(messages) and not _status_text:
        return
    workspace = getattr(bpy.context, "workspace", None)
    if workspace is None:
        return  # no window (headless): the owner's status property still says why
    scene = bpy.context.scene
    failing = [o.shapedeform.status for o in rig_format.owners(scene)] if scene is not None else []
    text = "; ".join(dict.fromkeys(m for m in list(messages) + failing if m))
    try:
        workspace.status_text_set(text or None)
    except (AttributeError, RuntimeError):
        return
    _status_text = text


def _pose(objects, depsgraph, final=None, refine=True):
    """Pose ``objects``' rigs and write their cages (``final``: with the Render budget; by
    default, :func:`rig.final_quality`); with ``refine``, have those a Viewport-budget solve
    left short refined once the updates pause. Returns why rigs failed ([str]).

    Blender evaluates again by itself when a depsgraph_update_post or frame_change_post
    handler tagged data (a second pass without callbacks), so what is evaluated when the
    update or frame change returns shows the new pose. Evaluating from inside the handler
    instead (``depsgraph.update()``) crashed Blender at the next update after a frame change,
    or after an update that rebuilt the depsgraph's relations (an object linked, hidden or
    parented, a modifier added).
    """
    if not objects:
        return []
    with paused():  # writing the cages makes Blender call us back
        messages = [rig.pose_safely(obj, depsgraph, final) for obj in objects
                    if not rig_format.is_baked(obj)]  # a baked rig's keys play (see bake.py)
    messages = [m for m in messages if m]
    _report(messages)
    if refine and not (final or rig.final_quality()):
        _refine_later(objects)
    return messages


def _refine_later(owners=None):
    """Have :func:`refine` run once the updates pause, if any of ``owners`` (by default, the
    scene's rigs) is unsettled. A refine already waiting for other rigs still runs."""
    if rig.unsettled(bpy.context.scene, owners):
        if bpy.app.timers.is_registered(refine):
            bpy.app.timers.unregister(refine)  # still moving: wait for the next pause
        bpy.app.timers.register(refine, first_interval=REFINE_AFTER)


# Seconds without an update before unsettled poses are solved with the Render budget.
REFINE_AFTER = 0.3


def refine():
    """Solve the current scene's unsettled rigs again with the Render budget (a timer)."""
    scene = bpy.context.scene
    objects = [o for o in rig.unsettled(scene) if not rig_format.is_baked(o)]
    if not objects:
        return None
    with paused():
        messages = [rig.pose_safely(obj, final=True) for obj in objects]
        bpy.context.view_layer.update()
    _report([m for m in messages if m])
    return None  # once


@persistent
def on_depsgraph_update(scene, depsgraph):
    """A handle moved (or a rigged object's handles did): solve and write at once.

    A duplicate of a rig's owner gets its follower's cage here, or, made together with handles
    of the rig, a rig of its own. A handle or pin made active (selecting evaluates) becomes its
    rig's list's active item. A pin moved off its point by hand is bound to the point it is
    left on (:func:`_pin_moved_by_hand`).
    """
    if _busy:
        return
    handles.follow_active_object(depsgraph.view_layer)
    moved = {}
    collections = [update.id for update in depsgraph.updates if isinstance(update.id, bpy.types.Collection)]
    held = set()  # the collections of rigs' handles and cages
    if collections:
        for obj in rig_format.bound_objects():  # an object moved between collections, perhaps a handle
            if rig_format.is_owner(obj):
                handles.keep_in_collection(obj)
                held.add(obj.shapedeform.handle_collection)
    # A character linked, overridden, appended or instanced updates a collection; one linked into
    # a scene (Ctrl+L) the scene alone. A handle's move updates its rig's collection of handles
    # (QA: the scenes were looked through on every step of a drag), which shows no character
    # (Bind makes it for the handles and the cage alone).
    if any(isinstance(update.id, bpy.types.Scene) for update in depsgraph.updates) or \
            any(collection.original not in held for collection in collections):
        # A collection instance pointed at another collection changes no scene's objects (QA).
        _lock_scenes(force=any(isinstance(update.id, bpy.types.Object) and update.id.instance_type == "COLLECTION"
                               for update in depsgraph.updates))
    duplicates.keep_islands_apart()  # a character appended twice
    for update in depsgraph.updates:
        if not isinstance(update.id, bpy.types.Object):
            continue
        obj = update.id.original
        duplicates.settle_duplicate(obj)
        if obj.library is None and (obj.shapedeform.is_bound or rig_format.watches_handles(obj)):
            rig_format.keep_handles_evaluated(obj)  # a handle deleted, the animation data replaced
        if (obj.type == "MESH" and obj.data.library is None and nodes.ISLAND in obj.data.attributes
                and rig_format.owner_of(obj) is None):
            mesh.forget_islands(obj)  # a rigged puppet joined into a mesh no rig deforms
        if obj.type == "GREASEPENCIL":
            grease_pencil.keep_marks(obj)  # layers added, deleted or joined in
        if rig_format.is_owner(obj) and update.is_updated_transform and obj.library is None:
            handles.keep_in_rig_space(obj)  # after Apply Transform or Set Origin
            handles.fit_pin_shapes(obj)  # its scale is its pins' too
        if rig_format.is_owner(obj) and rig.stale(obj):  # a setting driven or keyed, edited
            moved[obj.name] = obj
        owner = handles.rig_of(obj)
        if owner is None or obj.type != "EMPTY":
            continue
        is_pin = obj.shapedeform.pin_kind != "POSITION"
        if is_pin and update.is_updated_transform and _pin_moved_by_hand(obj, owner):
            moved[owner.name] = owner
        if owner.name in moved:
            continue  # posed once whatever else of it changed
        # Pins ride on the cage (vertex parents), so their moves come from the pose, and posing
        # again for them would never settle: only their amounts (driven, or a key edited at
        # this frame) pose again.
        if rig.stale(owner) if is_pin else update.is_updated_transform:
            moved[owner.name] = owner
    _pose(list(moved.values()), depsgraph)


def _pin_moved_by_hand(pin, owner):
    """Whether ``pin``, whose transform changed, was moved off its point and is bound now to
    the point it was left on (a script's move, with no window); with a window, once the move
    is over (:func:`_reseat_later`)."""
    if not handles.left_its_point(pin):
        return False
    if not _windowless():
        _reseat_later()
        return False
    return _reseat_pins(owner)


def _reseat_pins(owner):
    """Bind the pins of ``owner``'s rig that were moved by hand to the points they were left
    on; whether any was bound to another point. A library's rig keeps its pins' points: they
    go back on them, and the owner's status (shown in the status bar) says why."""
    try:
        return handles.reseat_pins(owner)
    except RigError as err:
        owner.shapedeform.status = str(err)
        _report([str(err)])
    except Exception:  # a handler must not raise; the pin stays where it was left
        traceback.print_exc()
    return False


def _reseat_later():
    """Have the moved pins re-seated once the move is over: once no update has moved them for
    ``REFINE_AFTER`` seconds and no transform (G, a gizmo) runs. A Location field dragged in
    the sidebar writes its start value plus the drag at every step, so a pin re-seated at each
    step would move by every step's sum."""
    if bpy.app.timers.is_registered(_reseat_dropped_pins):
        bpy.app.timers.unregister(_reseat_dropped_pins)
    bpy.app.timers.register(_reseat_dropped_pins, first_interval=REFINE_AFTER)


def _reseat_dropped_pins():
    """Re-seat the file's pins moved by hand (a timer); the writes call
    :func:`on_depsgraph_update`, which poses their rigs."""
    if _transforming():
        return REFINE_AFTER
    for owner in [obj for obj in rig_format.bound_objects() if rig_format.is_owner(obj)]:
        _reseat_pins(owner)
    return None


def _windowless():
    """Whether Blender runs without windows (a script, a farm), where nothing is dragged."""
    return bpy.app.background


def _transforming():
    """Whether a modal transform (G, R, S, a gizmo's drag) runs in some window."""
    windows = bpy.context.window_manager.windows if bpy.context.window_manager is not None else ()
    return any(op.bl_idname.startswith(("TRANSFORM_OT", "transform.")) for window in windows
               for op in window.modal_operators)


@persistent
def on_frame_change(scene, depsgraph):
    """Frames changed: animated handles have new transforms (of every rig the scene shows, a
    collection it instances from elsewhere included)."""
    if _busy:
        return
    # A frame stepped to stays on screen: solve it as a render would at once, rather than
    # showing the Viewport budget's pose and, a moment later, the refined one (a visible jump
    # on every step where a solve stops short). Playback and scrubbing keep the Viewport budget,
    # and leave the rigs the viewport does not show to be posed when they stop.
    owners = [o for o in rig_format.owners(scene, depsgraph) if o.shapedeform.handles]
    interactive = _interactive()
    if not interactive:
        failures = _pose(owners, depsgraph, final=True)
        if _windowless():  # a farm's render: its log is all anyone reads (QA: a frame failed unsaid)
            for message in failures:
                print(f"Shape Deform: frame {scene.frame_current_final:g}: {message}", file=sys.stderr, flush=True)
        return
    view_layer, seen = bpy.context.view_layer, []
    for obj in owners:
        if _unseen(obj, view_layer):
            rig.defer(obj)
        else:
            seen.append(obj)
    _pose(seen, depsgraph, final=False, refine=False)
    _refine_later(owners)  # the scene's rigs found once per frame: deferred ones too


def _unseen(owner, view_layer):
    """Whether the viewport shows nothing of ``owner``'s rig: the owner, in ``view_layer``, is
    hidden there or has its modifier off in the viewport, and no duplicate follows the rig
    (its cage's mesh has no other user). One shown through a collection instance, which cannot
    be told cheaply, counts as seen."""
    if owner.shapedeform.cage.data.users > 1 or view_layer.objects.get(owner.name) != owner:
        return False
    return not (owner.visible_get(view_layer=view_layer)
                and any(m.show_viewport for m in rig_format.modifiers_of(owner)))


def _interactive():
    """Whether frames are changing continuously: playback or scrubbing in a window."""
    screen = getattr(bpy.context, "screen", None)
    return screen is not None and (screen.is_animation_playing or screen.is_scrubbing)


@persistent
def on_undo(*_args):
    """Undo or redo: rigs are rebuilt lazily from the data of the step restored; a pose it
    restored that a Viewport solve left short is refined as after any move."""
    rig.forget()
    rig_format.forget_bound()
    _refine_later()


@persistent
def on_load(*_args):
    """A file was opened: rigs are rebuilt from the data saved in it, duplicates are settled
    as followers of their rig and every rig of the scene is posed, so a file edited while the extension was
    disabled (a handle moved, an object duplicated) shows what its handles say at once."""
    rig.forget()
    rig_format.forget_bound()
    sync_scene()


def sync_scene():
    """Bring an older version's node group up to date, repair duplicates and pose the current
    scene's rigs (a file opened, the extension enabled)."""
    nodes.upgrade()
    rig_format.relink_overrides()
    for obj in bpy.data.objects:
        duplicates.settle_duplicate(obj, opened=True)
        if rig_format.is_owner(obj) and obj.library is None:
            handles.keep_in_collection(obj)
            handles.put_pins_back(obj)
        if obj.shapedeform.is_bound or rig_format.watches_handles(obj):
            rig_format.keep_handles_evaluated(obj)  # a file from before the driver, the extension enabled again
    duplicates.keep_islands_apart()
    _lock_scenes()
    scene = bpy.context.scene
    if scene is not None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        _pose([o for o in rig_format.owners(scene, depsgraph) if o.shapedeform.handles], depsgraph)


# What _lock_scenes last looked at, per scene: which objects it has and which scenes it shows as
# its background set. An object or a collection instance linked into a scene changes them (review:
# Ctrl+L updates only the scene), and so does one linked and another unlinked at once (QA).
_lock_seen = {"scenes": None}


def _lock_scenes(force=False):
    """Lock Interface in the scenes that show rigs they did not bind (:func:`rig_format.lock_scenes_showing_rigs`),
    saying so on the console, as no operator runs to report it; only when ``force`` (a collection
    instance was pointed at another collection) or the scenes' objects or background sets changed."""
    seen = [_lock_key(scene) for scene in bpy.data.scenes]
    if seen == _lock_seen["scenes"] and not force:
        return
    _lock_seen["scenes"] = seen
    for scene in rig_format.lock_scenes_showing_rigs():
        print(f"Shape Deform: turned Render > Lock Interface on in scene '{scene.name}', which shows rigs: frame "
              "handlers pose them while a render reads the scene")


def _lock_key(scene):
    """What of ``scene`` decides which rigs it shows, short of what its collection instances
    instance: its objects (their count and the sum of their session ids: 2 ms at 10,000
    objects) and its chain of background sets (QA: a rig shown as a Background Set was not locked)."""
    uids = [obj.session_uid for obj in scene.objects]
    backgrounds, shown = [], scene.background_set
    while shown is not None and shown.session_uid not in backgrounds:
        backgrounds.append(shown.session_uid)
        shown = shown.background_set
    return scene.session_uid, len(uids), sum(uids), tuple(backgrounds)


_HANDLERS = (
    ("depsgraph_update_post", on_depsgraph_update),
    ("frame_change_post", on_frame_change),
    ("load_post", on_load),
    ("undo_post", on_undo),
    ("redo_post", on_undo),
)

classes = ()


def register():
    for name, function in _HANDLERS:
        getattr(bpy.app.handlers, name).append(function)
    # Enabled in an open file (Preferences): once Blender is idle, as data cannot be written
    # while add-ons register. Without a window loop the timer never runs: a script that enables
    # the extension in an open file calls sync_scene() itself (an older version's group and
    # followers are then brought up to date; until then they deform as that version did).
    bpy.app.timers.register(_sync_once, first_interval=0.0)


def _sync_once():
    sync_scene()
    return None  # once


def unregister():
    for timer in (refine, _sync_once, _reseat_dropped_pins):
        if bpy.app.timers.is_registered(timer):
            bpy.app.timers.unregister(timer)
    for name, function in _HANDLERS:
        functions = getattr(bpy.app.handlers, name)
        if function in functions:
            functions.remove(function)
    rig.forget()
