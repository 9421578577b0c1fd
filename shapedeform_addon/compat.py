# SPDX-License-Identifier: GPL-3.0-or-later
"""Where Blender's Python API differs between the versions the manifest claims (4.5 LTS on).

Each function here hides one difference, found by feature rather than by version number, so
the rest of the add-on calls one name on every Blender. Nothing here is registered.

- Keyframes live in an action's channelbag for a slot (Blender 4.4+). Blender 5.0 added
  ``bpy_extras.anim_utils.action_ensure_channelbag_for_slot``; 4.5 has only the getter, and
  the same is reached through the action's first layer and keyframe strip.
- Which actions an ID plays: its active action and its NLA strips' (a meta strip holding strips
  of its own), each with the slot it plays, as readers of keys need them on every version
  (and what holds each, to give it another); and so whether a property is keyed (or driven).
- A Geometry Nodes modifier's inputs: ID properties of the modifier keyed by socket identifier
  up to 5.1; from 5.2 ``modifier.properties.inputs.<identifier>.value`` (the modifier takes no
  ID properties).
- Where Blender draws a NURBS spline's samples: 5.0 on, ``resolution_u`` in every span of its
  knots; before, ``resolution_u`` per gap between points, evenly over the whole curve.
"""

import bpy
from bpy_extras import anim_utils


def ensure_channelbag(action, slot):
    """The channelbag of ``action`` for ``slot``, made (with a layer and strip) when missing.

    Parameters
    ----------
    action : bpy.types.Action
    slot : bpy.types.ActionSlot
        One of ``action.slots``.

    Returns
    -------
    bpy.types.ActionChannelbag
    """
    ensure = getattr(anim_utils, "action_ensure_channelbag_for_slot", None)
    if ensure is not None:
        return ensure(action, slot)
    layer = action.layers[0] if action.layers else action.layers.new("Layer")
    strip = layer.strips[0] if layer.strips else layer.strips.new(type="KEYFRAME")
    return strip.channelbag(slot, ensure=True)


def action_holders(animation):
    """What in ``animation`` (an ID's AnimData, or None) holds an action to play, each with
    ``action`` and ``action_slot`` (None where empty): ``animation`` itself (its active action)
    and every NLA strip, those inside meta strips included."""
    if animation is None:
        return []
    return [animation] + [strip for _, strip in nla_strips(animation)]


def nla_strips(animation):
    """(track, strip) for every NLA strip of ``animation`` (an ID's AnimData), those inside
    meta strips included, track by track."""
    return [(track, strip) for track in animation.nla_tracks for strip in _strips(track.strips)]


def played_actions(animation):
    """The (action, slot) pairs ``animation`` (an ID's AnimData, or None) plays: its active
    action's and every NLA strip's, those inside meta strips included; empty strips left out."""
    return [(holder.action, holder.action_slot) for holder in action_holders(animation) if holder.action is not None]


def _strips(strips):
    """Every strip of ``strips``, those inside meta strips included."""
    for strip in strips:
        yield strip
        yield from _strips(strip.strips)


def channelbag(action, slot):
    """The channelbag of ``action`` for ``slot``, or None when it has none."""
    return anim_utils.action_get_channelbag_for_slot(action, slot)


def is_animated(block, data_path):
    """Whether any component of ``block``'s (an ID's) property ``data_path`` is driven, or keyed
    in an action it plays (active, or in the NLA). (``fcurves.find`` reads one index only.)"""
    animation = block.animation_data
    if animation is not None and any(curve.data_path == data_path for curve in animation.drivers):
        return True
    bags = [channelbag(action, slot) for action, slot in played_actions(animation) if slot is not None]
    return any(curve.data_path == data_path for bag in bags if bag is not None for curve in bag.fcurves)


def modifier_input(modifier, identifier):
    """The value of a Geometry Nodes modifier's input (5.2 keeps inputs in ``properties``;
    earlier versions as ID properties of the modifier)."""
    interface = getattr(modifier, "properties", None)
    if interface is not None:
        socket = getattr(interface.inputs, identifier, None)
        return socket.value if socket is not None else None
    return modifier.get(identifier)


def modifier_input_property(modifier, identifier):
    """``(struct, property)`` of a Geometry Nodes modifier's input, for ``layout.prop`` (see
    :func:`modifier_input`)."""
    interface = getattr(modifier, "properties", None)
    if interface is not None:
        return getattr(interface.inputs, identifier), "value"
    return modifier, f'["{identifier}"]'


def set_modifier_input(modifier, identifier, value):
    """Set a Geometry Nodes modifier's input (see :func:`modifier_input`)."""
    interface = getattr(modifier, "properties", None)
    if interface is not None:
        getattr(interface.inputs, identifier).value = value
    else:
        modifier[identifier] = value


# The first Blender whose grease-pencil strokes say whether they are filled (``fill_id``).
STROKES_MARK_FILLS = (5, 1, 0)


def fills_strokes(material):
    """Whether a grease-pencil ``material`` may fill strokes drawn with it, closed or not.

    Up to Blender 5.0 the material's Fill switch decides for every stroke drawn with it. 5.1
    deprecates that switch (it reads False on materials that fill) and marks each filled stroke
    itself (:func:`filled_strokes`); there a material fills unless its fill is a holdout, which
    cuts a hole instead, as before. (By version: a drawing with no filled stroke has no mark to
    tell the two apart.)
    """
    style = material.grease_pencil if material is not None else None
    if style is None:
        return False
    if bpy.app.version >= STROKES_MARK_FILLS:
        return not style.use_fill_holdout
    return bool(style.show_fill and not style.use_fill_holdout)


def filled_strokes(material_fills, material_index, fill_id):
    """Per stroke, whether Blender draws it filled (cyclic or not).

    Parameters
    ----------
    material_fills : (m,) bool ndarray
        :func:`fills_strokes` of each material slot.
    material_index : (s,) int ndarray
        Each stroke's slot, within ``material_fills``.
    fill_id : (s,) int ndarray
        Blender 5.1's ``fill_id`` stroke attribute (0: not filled; strokes sharing an id make
        one fill); ignored up to 5.0, which has none.

    Returns
    -------
    (s,) bool ndarray
    """
    filled = material_fills[material_index]
    if bpy.app.version >= STROKES_MARK_FILLS:
        filled = filled & (fill_id != 0)
    return filled


# Blender draws a NURBS spline's samples span by span from this version on (found by drawing
# every order and knot kind on 4.5 and 5.0, tests/addon/test_rig_curve.py).
NURBS_SAMPLED_PER_SPAN = bpy.app.version >= (5, 0, 0)
