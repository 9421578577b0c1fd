# SPDX-License-Identifier: GPL-3.0-or-later
"""What a bake was made from, and whether the rig has changed since (the sidebar's "Out of date").

At a bake's end :func:`fingerprint` digests what its poses were made from: the rig's settings,
the handles (the points each holds, what sets their transforms: keys, drivers, the NLA, their
parenting and constraints), the pins, and the frames baked. ``rig_format.store_bake_source``
keeps it on the bake's Key. :func:`is_out_of_date` compares the rig as it is now, and keeps its
answer per rig until something it reads is updated (this module's handlers drop it). A render
names the rigs whose bakes are out of date on the console.
"""

import hashlib
import sys
import traceback

import bpy
import numpy as np
from bpy.app.handlers import persistent
from mathutils import Euler, Matrix, Quaternion, Vector

from ..solver.rigging.plane import affine_inverse
from ..solver.wording import by_count
from . import compat, rig_format


# The owner's settings its poses depend on when baked: the Viewport budget is not one (a bake
# solves with the Render one). Pins' are rig_format.PIN_SETTINGS.
BAKED_SETTINGS = tuple(f"shapedeform.{name}" for name in ("weight_laplacian", "weight_mvc", "weight_edge",
                                                         "preserve_area", "prevent_flips", "render_iterations"))
# A handle's own transform (a pin's is not read: it rides on its point): where it is and its
# size, and how it turns, which its rotation mode's values and the delta rotation make together.
HANDLE_LOCATION_SCALE = ("location", "scale", "delta_location", "delta_scale")
HANDLE_ROTATION = ("rotation_mode", "rotation_euler", "rotation_quaternion", "rotation_axis_angle",
                   "delta_rotation_euler", "delta_rotation_quaternion")
HANDLE_TRANSFORM = HANDLE_LOCATION_SCALE + HANDLE_ROTATION
# How a handle hangs from its parent, besides whether it has one and the parent inverse (the
# parent object itself is not followed).
HANDLE_PARENTING = ("parent_type", "parent_bone", "parent_vertices")
# What of a keyframe sets the curve: its place, its Bezier handles, how it runs to the next
# (its interpolation); and where it runs by an easing, how.
_KEYFRAME_FIELDS = (("co", 2, np.float32), ("handle_left", 2, np.float32), ("handle_right", 2, np.float32))
_EASING_FIELDS = (("easing", 1, np.int32), ("back", 1, np.float32), ("amplitude", 1, np.float32),
                  ("period", 1, np.float32))
_BEZIER = 2  # Keyframe.interpolation 'BEZIER' as foreach_get gives it: the easings come after it
# Properties of constraints, F-curve modifiers, NLA strips and driver targets that are no
# setting: what only the interface shows, and Set Inverse's request, which the next evaluation
# carries out (writing the inverse, which counts).
_NOT_SETTINGS = frozenset({"rna_type", "name", "select", "active", "show_expanded", "set_inverse_pending"})
# An NLA strip's influence and time are worked out on each frame (from its blend in and out,
# and its frames) unless animated, and then their curves count.
_STRIP_CONTROLS = frozenset({"influence", "strip_time"})
# Numbers that no key sets are the same within this (relative and absolute): Apply Transform on
# the owner gives its handles' transforms back in rig space with rounding errors (4.7e-8
# measured), which move nothing; values rounded to a fixed step changed wherever such an error
# crossed a step (-0.70000503 to -0.70000499).
TOLERANCE = 1e-5


class _Source:
    """What a bake is made from, as :func:`fingerprint` gathers it: ``parts`` that must stay
    exactly as they are (keys, drivers, choices, names of what each number is), and ``numbers``
    (float values no key sets), which may move by rounding errors."""

    def __init__(self):
        self.parts = []
        self.numbers = []

    def add(self, label, value):
        """Add ``value`` (one component of a property), ``label`` saying what it is."""
        if isinstance(value, float):
            self.parts.append(label)
            self.numbers.append(value)
        else:
            self.parts.append((label, value))

    def digest(self):
        parts = [part if isinstance(part, bytes) else repr(part).encode() for part in self.parts]
        return hashlib.blake2b(b"\0".join(parts), digest_size=16).hexdigest()


def fingerprint(obj):
    """What owner ``obj``'s rig makes its bake from: the rig's settings, the handles (the
    points each holds, and what sets their transforms: their own, their parenting and
    constraints), the pins (their points and amounts), and the frames its bake holds (the
    names of its keys).

    What is keyed or driven counts by its drivers and keys (place, Bezier handles,
    interpolation and easing; the curves' modifiers; the NLA tracks and strips that play them,
    and how), what is not by its value, so changing frames, saving and undo leave it as it was.
    A rotation no key sets counts by the turn it makes, however its values write it (Apply
    Transform writes -q for a quaternion q, -pi for an Euler angle of pi). Objects that
    drivers, constraints and parents name count only by being named (renaming one changes
    nothing), and what they do is not followed. No frame is evaluated and keys are read in bulk,
    yet every key counts: 20 ms for 30 handles keyed on each of 500 frames, which is why
    :func:`is_out_of_date` keeps its answer.

    Returns
    -------
    digest : str
        Hexadecimal, of everything but the numbers no key sets (and of what each number is).
    numbers : (k,) float64 ndarray
        Those numbers; compared within :data:`TOLERANCE` (:func:`is_out_of_date`).

    Together they change when anything that changes the bake's poses does, as far as the rig
    can tell.
    """
    source = _Source()
    key = obj.shapedeform.cage.data.shape_keys
    source.parts.append(tuple(key.key_blocks.keys()) if key is not None else ())
    _add_values(source, obj, BAKED_SETTINGS, _add_animation(source, obj, BAKED_SETTINGS.__contains__))
    to_rig = affine_inverse(rig_format.rig_to_object(obj))
    for empty, indices, offsets in rig_format.handle_items(obj):
        source.parts += [indices.tobytes(), offsets.tobytes()]
        _add_handle(source, empty, obj, to_rig)
    for kind, names in rig_format.PIN_SETTINGS.items():
        paths = tuple(f"shapedeform.{name}" for name in names)
        for empty, point in rig_format.pin_items(obj, kind):
            source.parts.append((kind, point))
            _add_values(source, empty, paths, _add_animation(source, empty, paths.__contains__))
    return source.digest(), np.array(source.numbers, dtype=np.float64)


# The answers of :func:`is_out_of_date` by owner (``session_uid``): the sidebar asks on every
# redraw, and working it out reads every key of every handle (20 ms for 30 handles keyed on 500
# frames). This module owns it; an owner's answer is dropped by any evaluation that updates the
# owner, its cage, handles or pins, and every answer by one that updates an action
# (:func:`forget_updated`, from this module's depsgraph and frame change handlers), on loading a file,
# undo and redo (its other handlers), and by baking the owner or clearing its bake.
_out_of_date = {}


def forget(obj=None):
    """Drop the answer :func:`is_out_of_date` keeps for owner ``obj`` (every owner's when None)."""
    if obj is None:
        _out_of_date.clear()
    else:
        _out_of_date.pop(obj.original.session_uid, None)


def forget_updated(depsgraph):
    """Drop the answers :func:`is_out_of_date` keeps for the rigs whose owner, cage, handles or
    pins ``depsgraph`` updated, and every answer when it updated an action (which rigs play it
    is as costly to find as the answers). A frame change evaluates the edits made since the last
    update with the frame, and calls no depsgraph handler: its updates count too (an animated
    rig's answer is worked out again if the sidebar draws the new frame)."""
    if not _out_of_date:
        return
    for update in depsgraph.updates:
        if isinstance(update.id, bpy.types.Action):
            _out_of_date.clear()
            return
        if isinstance(update.id, bpy.types.Object):
            forget(rig_format.owner_of(update.id.original) or update.id)


def is_out_of_date(obj):
    """Whether the rig of ``obj`` (its owner, a handle, or a duplicate following it) plays a
    bake made from other handles, pins or settings than it now has (:func:`fingerprint`); False
    when not baked, or baked before bakes kept a digest.

    The answer is kept until something it depends on is updated (:data:`_out_of_date`): a
    script's change counts once the depsgraph has evaluated it (``view_layer.update()``), as
    evaluated data does."""
    owner = rig_format.owner_of(obj)
    if owner is None:
        return False
    uid = owner.session_uid
    if uid not in _out_of_date:
        try:
            _out_of_date[uid] = _differs_from_bake(owner)
        except Exception:  # saved data a script damaged (posing the rig says so): a panel's draw must not fail
            traceback.print_exc()
            _out_of_date[uid] = False
    return _out_of_date[uid]


def _differs_from_bake(obj):
    """:func:`is_out_of_date`, worked out."""
    made_from = rig_format.bake_source(obj.shapedeform.cage)
    if made_from is None:
        return False
    digest, numbers = fingerprint(obj)
    return digest != made_from[0] or not np.allclose(numbers, made_from[1], rtol=TOLERANCE, atol=TOLERANCE,
                                                     equal_nan=True)


def _sets_handle(path):
    """Whether a handle's property ``path`` sets where it is: its transform, its constraints'."""
    return path in HANDLE_TRANSFORM or path.startswith("constraints[")


def _add_handle(source, handle, owner, to_rig):
    """Add what sets where ``handle`` is: what animates it, its own transform, its parenting
    (its parent inverse in rig space, ``to_rig`` (4, 4) from ``owner``'s space, while it hangs
    from the owner: Apply Transform on the owner changes both), its constraints."""
    animated = _add_animation(source, handle, _sets_handle)
    _add_transform(source, handle, animated)
    source.parts.append(("parented", handle.parent is not None))
    _add_values(source, handle, HANDLE_PARENTING, animated)
    inverse = np.array(handle.matrix_parent_inverse, dtype=np.float64)
    if handle.parent == owner and handle.parent_type == "OBJECT":
        inverse = to_rig @ inverse
    for i, value in enumerate(inverse.ravel()):
        source.add(("parent inverse", i), float(value))
    for i, constraint in enumerate(handle.constraints):
        _add_settings(source, ("constraint", i, constraint.type), constraint, animated,
                      f"{constraint.path_from_id()}.")
        for k, target in enumerate(getattr(constraint, "targets", ())):  # an Armature constraint's list
            _add_settings(source, ("constraint target", i, k), target, animated, f"{target.path_from_id()}.")


def _add_animation(source, block, wanted):
    """Add what animates ``block``'s properties whose paths ``wanted`` (a callable) accepts: the
    actions it plays and how (active, or in NLA tracks and strips), their F-curves of those
    properties, its drivers of them; returns the components they set, {(path, index)}."""
    animation = block.animation_data
    if animation is None:
        return set()
    played = {}  # each (action, slot) played: its number and its curves of wanted properties
    strips = compat.nla_strips(animation)
    # In NLA tweak mode the action tweaked is the active one as well as its strip's: it counts
    # as the strip's.
    if animation.action is not None and not animation.use_tweak_mode:
        number = _played(played, animation, wanted)
        if number is not None and strips:  # it blends over them so (with none, it plays as it is)
            source.parts.append(("action", number, animation.action_blend_type, animation.action_extrapolation))
            source.add("action influence", animation.action_influence)
    sounding = _add_nla(source, animation, strips, played, wanted)
    if animation.action is not None:
        sounding.add((animation.action, animation.action_slot))
    driven = [curve for curve in animation.drivers if wanted(curve.data_path)]
    curves = [curve for _, keyed in played.values() for curve in keyed] + driven
    for curve in curves:
        _add_curve(source, curve)
        if curve.driver is not None:
            _add_driver(source, curve.driver)
    # A curve that does not play (muted, no keys, in a muted track or with the NLA off) sets
    # nothing: its property's own value counts (QA: a muted handle moved by hand left the bake
    # up to date, 0.5 off).
    playing = [curve for key, (_, keyed) in played.items() if key in sounding for curve in keyed] + driven
    return {(curve.data_path, curve.array_index) for curve in playing
            if not curve.mute and (curve.driver is not None or len(curve.keyframe_points) or len(curve.modifiers))}


def _played(played, holder, wanted):
    """The number ``holder`` (AnimData, or an NLA strip) plays in ``played``, the actions played
    (each (action, slot) once, with its curves of wanted properties read once); None when it
    plays none of them."""
    if holder.action is None or holder.action_slot is None:
        return None
    key = (holder.action, holder.action_slot)
    if key not in played:
        bag = compat.channelbag(*key)
        keyed = [curve for curve in bag.fcurves if wanted(curve.data_path)] if bag is not None else []
        played[key] = (len(played), _in_order(keyed))
    number, keyed = played[key]
    return number if keyed else None


def _add_nla(source, animation, strips, played, wanted):
    """Add how ``animation``'s NLA (``strips``, :func:`.compat.nla_strips`) plays the actions
    that set wanted properties: the tracks holding a strip of one, whole (each strip's settings
    and action's number in ``played``). Returns the (action, slot) pairs of its strips that
    play (the NLA on, the track unmuted and soloed where one is, the strip unmuted)."""
    tracks = {}
    for track, strip in strips:
        tracks.setdefault(track, []).append(strip)
    solo = any(track.is_solo for track in animation.nla_tracks)
    sounding = {(strip.action, strip.action_slot) for track, strip in strips
                if animation.use_nla and not track.mute and (track.is_solo or not solo) and not strip.mute}
    counted = False
    for i, (track, its_strips) in enumerate(tracks.items()):
        numbers = [_played(played, strip, wanted) for strip in its_strips]
        if all(number is None for number in numbers):
            continue  # plays nothing the rig reads
        counted = True
        source.parts.append(("track", i, track.mute, track.is_solo))
        for strip, number in zip(its_strips, numbers):
            source.parts.append(("strip", number))
            controls = [curve for curve in strip.fcurves if curve.data_path in _STRIP_CONTROLS]
            for curve in controls:
                _add_curve(source, curve)
            _add_settings(source, "strip", strip, skip=_STRIP_CONTROLS)
    if counted:  # a solo track elsewhere keeps these from playing
        source.parts.append(("nla", animation.use_nla, solo))
    return sounding


def _in_order(curves):
    """``curves`` by property, whatever order channel groups put them in."""
    return sorted(curves, key=lambda curve: (curve.data_path, curve.array_index))


def _add_values(source, block, paths, animated):
    """Add the value of each component of ``block``'s properties ``paths`` that no curve sets
    (not in ``animated``)."""
    for path in paths:
        for i, value in enumerate(_components(block.path_resolve(path))):
            if (path, i) not in animated:
                source.add((path, i), value)


def _add_settings(source, label, struct, animated=frozenset(), prefix="", skip=frozenset()):
    """Add the settings of ``struct`` (a constraint, an F-curve modifier, an NLA strip, a
    driver's target): the value of each component of its editable properties no curve sets (not
    in ``animated``, its paths starting with ``prefix``), but for its collections and the
    properties named in ``skip``, and only whether its pointers are set (an object is named,
    not followed)."""
    source.parts.append((label, struct.bl_rna.identifier))
    for prop in struct.bl_rna.properties:
        name = prop.identifier
        if prop.is_readonly or prop.type == "COLLECTION" or name in _NOT_SETTINGS or name in skip:
            continue
        value = getattr(struct, name)
        if prop.type == "POINTER":
            value = value is not None
        for i, component in enumerate(_components(value)):
            if (prefix + name, i) not in animated:
                source.add(name, component)


def _add_transform(source, handle, animated):
    """Add the values of ``handle``'s own transform that no curve sets (not in ``animated``):
    while none sets its rotation, the turn it makes rather than the values that write it."""
    paths = HANDLE_LOCATION_SCALE
    if any(path in HANDLE_ROTATION for path, _ in animated):
        paths += HANDLE_ROTATION
    else:
        for i, value in enumerate(np.ravel(_rotation(handle))):
            source.add(("rotation", i), float(value))
    _add_values(source, handle, paths, animated)


def _rotation(block):
    """The rotation (3, 3) ``block``'s rotation values make, its delta rotation's included, as
    Blender makes it (quaternions normalised; no delta in axis-angle mode)."""
    mode = block.rotation_mode
    if mode == "QUATERNION":
        own, delta = Quaternion(block.rotation_quaternion), Quaternion(block.delta_rotation_quaternion)
        return delta.normalized().to_matrix() @ own.normalized().to_matrix()
    if mode == "AXIS_ANGLE":
        angle, *axis = block.rotation_axis_angle
        return Matrix.Rotation(angle, 3, Vector(axis))
    return Euler(block.delta_rotation_euler, mode).to_matrix() @ Euler(block.rotation_euler, mode).to_matrix()


def _components(value):
    """A property's value as a flat tuple of its components: one for a number, a flag, an enum
    or a set of enum flags (sorted), a matrix's row by row."""
    if isinstance(value, Matrix):
        return tuple(component for row in value for component in row)
    if isinstance(value, (set, frozenset)):
        return (tuple(sorted(value)),)
    return tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else (value,)


def _add_curve(source, curve):
    """Add what ``curve`` (an F-curve) sets: which property, its keyframes (read in bulk, how
    they ease where any does), its extrapolation, whether muted, its modifiers' settings."""
    points = curve.keyframe_points
    interpolation = np.empty(len(points), dtype=np.int32)
    points.foreach_get("interpolation", interpolation)
    fields = _KEYFRAME_FIELDS + (_EASING_FIELDS if np.any(interpolation > _BEZIER) else ())
    source.parts.append((curve.data_path, curve.array_index, curve.extrapolation, curve.mute))
    source.parts.append(interpolation.tobytes())
    for name, width, dtype in fields:
        values = np.empty(len(points) * width, dtype=dtype)
        points.foreach_get(name, values)
        source.parts.append(values.tobytes())
    for i, modifier in enumerate(curve.modifiers):
        _add_settings(source, ("modifier", i), modifier)


def _add_driver(source, driver):
    """Add how ``driver`` computes its value: not the values it reads, nor which objects it
    reads them from (renaming one would change its name; the README says what drivers read is
    not followed)."""
    source.parts.append((driver.type, driver.expression, driver.use_self))
    for variable in driver.variables:
        source.parts.append((variable.name, variable.type))
        for target in variable.targets:
            _add_settings(source, "target", target)


@persistent
def _forget_updated(_scene, depsgraph):
    """Depsgraph update and frame change: :func:`forget_updated`."""
    forget_updated(depsgraph)


@persistent
def _forget_all(*_args):
    """A file opened, undo or redo: every answer goes (the data it read was replaced)."""
    forget()


@persistent
def _warn_of_stale_bakes(scene, *_args):
    """A render starts: name the rigs it plays out-of-date bakes of on the console, which is
    all a farm's render leaves to read (QA: a key edited after baking rendered the old motion
    unsaid; the sidebar alone said so). Only the objects the scene shows are looked through,
    not a depsgraph: an interactive render calls this from its own thread."""
    try:
        stale = [obj.name for obj in rig_format.owners(scene, evaluated=False)
                 if rig_format.is_baked(obj) and is_out_of_date(obj)]
    except Exception:  # a render must not fail for a warning
        traceback.print_exc()
        return
    if stale:
        rigs = ", ".join(repr(name) for name in stale)
        made = by_count(len(stale), "plays a bake made before its rig", "play bakes made before their rigs")
        print(f"Shape Deform: {rigs} {made} last changed, so the render shows the motion as baked: Bake Again to "
              "render the motion the handles give now", file=sys.stderr, flush=True)


_HANDLERS = (("depsgraph_update_post", _forget_updated), ("frame_change_post", _forget_updated),
             ("load_post", _forget_all), ("undo_post", _forget_all), ("redo_post", _forget_all),
             ("render_init", _warn_of_stale_bakes))

classes = ()


def register():
    for name, function in _HANDLERS:
        getattr(bpy.app.handlers, name).append(function)


def unregister():
    for name, function in _HANDLERS:
        functions = getattr(bpy.app.handlers, name)
        if function in functions:
            functions.remove(function)
    forget()
