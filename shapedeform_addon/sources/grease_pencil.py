# SPDX-License-Identifier: GPL-3.0-or-later
"""Grease pencil (GPv3): the current frame's drawings of all layers, or the chosen ones.

The graph is built inside the silhouette of the current frame's strokes (each swept by its
radius, closed strokes filled). The drawings are never written: the Shape Deform modifier maps
the points of every drawing of every keyframe, the animator's later drawings too, in layer space
(Geometry Nodes do not see layer transforms); stroke radii keep their size. When only some
layers are chosen, a boolean LAYER attribute (``sd_rigged``, or ``sd_rigged.001`` and so on
when another object's rig on the same data has that name) marks them and the modifier deforms
only those.

An older version wrote poses into the drawings of the frame it was bound on, keeping their
rest in each drawing's ``sd_rest`` attribute and the drawings' (layer, frame) on
``obj.shapedeform``; :func:`restore_legacy` gives those back.
"""

import numpy as np

from ...solver.outline import outline_graph, parts_graph
from ...solver.rigging.plane import fit_plane
from ...solver.rigging.silhouette import stroke_silhouette
from ...solver.wording import by_count
from .. import compat, rig_format
from ..errors import RigError
from .prepared import Prepared
from ..nodes import ISLAND, ORDER_INPUT, RIGGED
from ..rig_format import (LAYER_ISLANDS, LEGACY_GP_FRAMES, LEGACY_GP_LAYERS, RIGGED_ALL, RIGGED_COUNT, RIGGED_KEY,
                          RIGGED_NAMES, modifiers_of)
from .mesh import REST_ATTRIBUTE, forget_islands, mark_islands, read_vectors

# Strokes thinner than this fraction of the drawing's size are swept this wide, so a hairline
# drawing still has an area to deform.
MIN_RADIUS_FRACTION = 0.005
# The most layers Layers Apart rigs: their islands are numbered from 1 in a byte (see prepare).
MAX_PARTS = 127


def _chosen_layers(obj, settings):
    layers = obj.data.layers
    whole = settings.layers.strip()  # one layer whose name has a comma in it, or a list
    names = [whole] if whole in layers else [n.strip() for n in settings.layers.split(",") if n.strip()]
    missing = [n for n in names if n not in layers]
    if missing:
        raise RigError(f"'{obj.name}' has no layer {', '.join(repr(n) for n in missing)}")
    # In drawing order, the top layer last, whatever order the names come in: Layers Apart
    # numbers its parts so, and a handle where parts lie level goes on the last (the one shown).
    return [layer for layer in layers if layer.name in names] if names else list(layers)


def bound_frames(obj):
    """(layer name, frame number) of each drawing an older version's rig wrote into."""
    settings = obj.shapedeform
    names = settings.get(LEGACY_GP_LAYERS, "").split("\n")
    return [(name, int(number)) for name, number in zip(names, settings.get(LEGACY_GP_FRAMES, []))]


def drawing_at(obj, name, number):
    """The drawing of layer ``name`` keyed at frame ``number``, or None when it is gone."""
    layer = obj.data.layers.get(name)
    frame = next((f for f in layer.frames if f.frame_number == number), None) if layer else None
    return frame.drawing if frame is not None else None


def _points(drawing):
    attribute = drawing.attributes.get("position")
    count = len(attribute.data) if attribute is not None else 0
    return read_vectors(attribute, count) if count else np.empty((0, 3), np.float32)


def _stroke_offsets(drawing):
    """(s + 1,) int64: each stroke's first point, then the point count."""
    offsets = np.empty(len(drawing.curve_offsets), dtype=np.int64)
    drawing.curve_offsets.foreach_get("value", offsets)
    return offsets


def _values(drawing, name, count, dtype, default):
    attribute = drawing.attributes.get(name)
    values = np.full(count, default, dtype=dtype)
    if attribute is not None and len(attribute.data) == count:
        attribute.data.foreach_get("value", values)
    return values


def stroke_order_losses(obj):
    """What the modifier's Stroke Order would change in renders of ``obj`` while the pose folds
    the shape over itself, as phrases for a message (empty when nothing shows).

    While a stroke lies over or under a fold, Stroke Order draws each layer as up to three
    layers with its name and settings (lighting, blend mode, opacity, tint, transform, parent,
    view-layer filter and pass index are kept): Sort Elements does not sort grease-pencil
    strokes. Those layers are in no layer group, and hold the current frame's drawing alone,
    keyed at frame 0. So a later modifier filtered by a layer group finds none, a Build modifier
    after the rig's, which times strokes from their keyframe, draws nothing, a Noise modifier's
    Random re-seeds, a drawing keyed before frame 0 vanishes, and a mask, which names its
    layers, finds one of the three. (The viewport's onion skins of other keyframes vanish too
    while a stroke lies on a fold; renders have none. Hidden layers and groups are left out
    before any modifier.)
    """
    layers = list(obj.data.layers)
    stack, ours = list(obj.modifiers), modifiers_of(obj)
    # Before Bind adds the rig's modifier, only those pinned last will come after it.
    later = stack[stack.index(ours[0]) + 1:] if ours else [m for m in stack if m.use_pin_to_last]
    checks = (
        ("masks of", [layer for layer in layers if layer.use_masks and len(layer.mask_layers)]),
        ("drawings before frame 0 of", [layer for layer in layers if any(f.frame_number < 0 for f in layer.frames)]),
        # Build times strokes from their keyframe; Noise's Random re-seeds every few frames
        # counted from it (at rest it moved points 0.05 on a drawing 3 tall).
        ("the keyframe timing read by", [m for m in later if m.type == "GREASE_PENCIL_BUILD"
                                         or (m.type == "GREASE_PENCIL_NOISE" and m.use_random)]),
        # Seeds and offsets counted by layer or stroke (QA, the figure folded: Offset by layer
        # moved the body 0.10, by stroke 0.05, at random 0.16; Noise's seed 0.006; Length's
        # random 0.06).
        ("the layer and stroke order read by", [m for m in later if (m.type == "GREASE_PENCIL_NOISE" and not m.use_random)
                                                or (m.type == "GREASE_PENCIL_OFFSET" and m.offset_mode != "MATERIAL")
                                                or (m.type == "GREASE_PENCIL_LENGTH" and m.use_random)]),
        ("the layer group filtering", [m for m in later if getattr(m, "use_layer_group_filter", False)
                                       and getattr(m, "tree_node_filter", "")]),
    )
    return [f"{what} " + ", ".join(f"'{item.name}'" for item in found) for what, found in checks if found]


def prepare(obj, settings):
    """Read the object's rest shape and build its graph, changing nothing (see :mod:`.sources`)."""
    frames = [(layer, layer.current_frame()) for layer in _chosen_layers(obj, settings)]
    # A layer's keyframe may hold an empty drawing (Add > Grease Pencil > Stroke makes one).
    frames = [(layer, frame) for layer, frame in frames
              if frame is not None and frame.drawing is not None and len(frame.drawing.strokes)]
    if not frames:
        raise RigError(f"'{obj.name}' has no strokes on the current frame")
    # A holdout fill cuts a hole; a stroke past the last slot is drawn unfilled: the extra
    # False at the end stands for it.
    fills = np.array([compat.fills_strokes(slot.material) for slot in obj.material_slots] + [False])
    strokes = [_strokes(frame.drawing, fills) for _, frame in frames]
    rest = np.concatenate([points for points, *_ in strokes])
    if len(rest) == 0:
        raise RigError(f"'{obj.name}' has no stroke points on the current frame")
    apart = settings.layers_apart and len(strokes) > 1
    if apart and len(strokes) > MAX_PARTS:
        raise RigError(f"'{obj.name}': Layers Apart rigs up to {MAX_PARTS} layers with strokes, and it has "
                       f"{len(strokes)}: choose fewer in Layers, or turn Layers Apart off")
    try:
        # Straight strokes lie in many planes: the one Blender draws in by default, local XZ.
        plane = fit_plane(rest, line_normal=(0.0, 1.0, 0.0))
        size = float(np.linalg.norm(np.ptp(plane.to_2d(rest), axis=0)))

        def silhouette(drawings):
            points, offsets, radii, filled = (np.concatenate(values) for values in zip(*_numbered_from(drawings)))
            return stroke_silhouette(plane.to_2d(points), offsets, radii, filled, min_radius=MIN_RADIUS_FRACTION * size)

        if apart:  # each layer a part of its own, which overlaps others without joining them
            graph, part = parts_graph([silhouette([drawing]) for drawing in strokes], settings.density)
        else:
            graph = outline_graph(silhouette(strokes), settings.density)
    except ValueError as err:
        raise RigError(f"'{obj.name}' cannot be rigged: {err}") from None
    # Each layer's island, from 1 (0: a layer not rigged, or with nothing drawn on this frame).
    # Numbers of the drawing's, not the file's (as a mesh's): the layers keep them in a byte
    # (Blender 5.0-5.2 crash when a grease pencil whose layers have a wider attribute is joined
    # into another, at the next file load), and a join gets them back by name (keep_marks).
    layer_islands, own = _layer_islands(obj, [layer for layer, _ in frames], settings) if apart else (None, None)
    islands = own[part] if apart else None

    # Every layer named, also one with nothing drawn yet on this frame.
    chosen = {layer.name for layer in _chosen_layers(obj, settings)} if settings.layers.strip() else None

    def commit(o):
        name = ""
        if chosen is not None:
            name, number = RIGGED, 0
            while name in o.data.attributes:  # another rig of this data marks its own layers
                number += 1
                name = f"{RIGGED}.{number:03d}"
            marks = np.array([layer.name in chosen for layer in o.data.layers], dtype=bool)
            o.data.attributes.new(name, "BOOLEAN", "LAYER").data.foreach_set("value", marks)
            _remember_layers(o, [layer.name for layer in o.data.layers], marks)
        o.shapedeform[RIGGED_KEY] = name
        if layer_islands is not None:
            mark_islands(o, layer_islands, "LAYER", "INT8")
            layers = [layer.name for layer in o.data.layers]
            sharing = [other for other in rig_format.other_rigged_users(o) if LAYER_ISLANDS in other.shapedeform]
            for user in [o, *sharing]:  # what each puts back by name when layers come or go
                _remember_layers(user, layers, islands=layer_islands)

    # Stroke Order is on wherever it costs the drawing nothing.
    rigged = [layer for layer, _ in frames]
    advice = "; ".join(filter(None, (_transformed_layers_advice(obj, rigged),
                                       _hidden_layers_advice(rigged, settings))))
    return Prepared(plane, graph, commit, advice=advice, modifier_inputs={ORDER_INPUT: not stroke_order_losses(obj)},
                    islands=islands)


def _layer_islands(obj, rigged, settings):
    """The island numbers (l,) int32 of all of ``obj``'s layers for a rig whose parts are the
    ``rigged`` layers, in order, and those of its parts (k,) int32.

    Numbers that other rigs of the drawing's data gave its layers are kept, so that those rigs
    still read theirs (QA: a copy bound with other layers apart renumbered them, and moved the
    first rig's arm 0.24 with no word); a rigged layer without one gets the next free number.

    Raises
    ------
    RigError
        More numbers than a layer keeps, or a chosen layer with nothing drawn on this frame
        that another rig numbered among this one's.
    """
    data = obj.data
    names = [layer.name for layer in data.layers]
    # The rigs of this data that keep layers apart: their numbers are on the layers.
    apart = [other for other in rig_format.other_rigged_users(obj) if LAYER_ISLANDS in other.shapedeform]
    attribute = _layer_attribute(data, ISLAND, "INT8") if apart else None
    numbers = _layer_values(attribute, len(names)) if attribute is not None else np.zeros(len(names), np.int32)
    place = {name: i for i, name in enumerate(names)}
    rigged_at = np.array([place[layer.name] for layer in rigged])
    fresh = rigged_at[numbers[rigged_at] == 0]
    numbers[fresh] = numbers.max(initial=0) + 1 + np.arange(len(fresh), dtype=np.int32)
    if numbers.max() > MAX_PARTS:
        raise RigError(f"'{obj.name}': with the rig of '{apart[0].name}', which shares its drawing, Layers Apart "
                       f"would number more than {MAX_PARTS} layers: choose fewer in Layers, or give it a drawing of "
                       "its own (Object > Relations > Make Single User)")
    own = numbers[rigged_at]
    empty = [layer.name for layer in _chosen_layers(obj, settings)
             if place[layer.name] not in rigged_at and own.min() <= numbers[place[layer.name]] <= own.max()]
    if empty:
        number = numbers[place[empty[0]]]  # every rig keeps all layers' numbers: its cage says its own
        holder = next((other for other in apart if number in set(rig_format.islands_of(other.shapedeform.cage.data))),
                      apart[0])
        raise RigError(f"'{obj.name}': its layer '{empty[0]}', kept apart by the rig of '{holder.name}' "
                       "(which shares its drawing), has nothing drawn on this frame: bind on a frame where it has "
                       "strokes, leave it out of Layers, or give it a drawing of its own (Make Single User)")
    return numbers, own


def _strokes(drawing, fills):
    """A drawing's strokes as the silhouette reads them: points (p, 3), each stroke's end
    (s,), radii (p,) and whether it is filled (s,); ``fills`` (m + 1,) tells which material
    slots fill (the last stands for a stroke past the last slot)."""
    points = _points(drawing)
    offsets = _stroke_offsets(drawing)
    strokes = len(offsets) - 1
    radii = _values(drawing, "radius", len(points), np.float32, 0.0)
    # Blender fills a stroke whether or not it is closed (see compat.filled_strokes).
    material = np.clip(_values(drawing, "material_index", strokes, np.int32, 0), 0, len(fills) - 1)
    fill_id = _values(drawing, "fill_id", strokes, np.int32, 0)
    closed = _values(drawing, "cyclic", strokes, bool, False)
    return points, offsets[1:], radii, closed | compat.filled_strokes(fills, material, fill_id)


def _numbered_from(strokes):
    """:func:`_strokes` of several drawings, the stroke ends of each counted on from the last
    point of the ones before, with a leading 0 on the first: what joins them into one."""
    start, numbered = 0, []
    for k, (points, ends, radii, filled) in enumerate(strokes):
        numbered.append((points, np.concatenate([[0], ends + start]) if k == 0 else ends + start, radii, filled))
        start += len(points)
    return numbered


def _hidden_layers_advice(layers, settings):
    """Advice on hidden layers rigged because no layers were named ("" when none is)."""
    hidden = [layer.name for layer in layers if _hidden(layer)] if not settings.layers.strip() else []
    if not hidden:
        return ""
    count = len(hidden)
    return (f"the hidden {by_count(count, 'layer', 'layers')} {', '.join(map(repr, hidden))} "
            f"{by_count(count, 'is', 'are')} part of the shape: name the layers to rig in Layers to leave "
            f"{by_count(count, 'it', 'them')} out")


def _hidden(layer):
    """Whether ``layer`` is hidden, by itself or by a layer group it is in (QA: a layer hidden
    by its group was rigged without a word)."""
    group = layer
    while group is not None:
        if group.hide:
            return True
        group = group.parent_group
    return False


def _transformed_layers_advice(obj, layers):
    """Advice on rigged layers that a transform of their own or their parent's moves ("" when
    none is): the rig reads and deforms strokes in their layer's space, where it has not moved
    them."""
    moved = [layer.name for layer in layers if not np.allclose(_layer_to_object(obj, layer), np.eye(4), atol=1e-6)]
    if not moved:
        return ""
    return (f"{', '.join(map(repr, moved))} {by_count(len(moved), 'is', 'are')} moved by a layer transform or "
            "parent: the rig works where the strokes lie without it, so put handles there (or apply the layer "
            "transform, or clear the parent, and bind again)")


def _layer_to_object(obj, layer):
    """(4, 4): where ``layer``'s transform and parent (object or bone) put its strokes in the
    object's space."""
    matrix = np.array(layer.matrix_local, dtype=np.float64)
    parent = layer.parent
    if parent is None:
        return matrix
    parent_world = np.array(parent.matrix_world, dtype=np.float64)
    bone = parent.pose.bones.get(layer.parent_bone) if parent.type == "ARMATURE" and layer.parent_bone else None
    if bone is not None:
        parent_world = parent_world @ np.array(bone.matrix, dtype=np.float64)
    return np.linalg.inv(np.array(obj.matrix_world, dtype=np.float64)) @ parent_world @ \
        np.array(layer.matrix_parent_inverse, dtype=np.float64) @ matrix


def unbind(obj):
    """Give back what binding changed; what could not be, as phrases (see :mod:`.sources`).

    The attribute marking the rigged layers goes unless another rig of this data names it too
    (a linked duplicate, following the rig or given a rig of its own with its handles); so do
    the layers' islands."""
    name = _rigged_attribute(obj)
    attribute = obj.data.attributes.get(name) if name else None
    if attribute is not None and name not in map(_rigged_attribute, rig_format.other_rigged_users(obj)):
        obj.data.attributes.remove(attribute)
    forget_islands(obj)
    return []


def _rigged_attribute(obj):
    """The name of the attribute marking the layers ``obj``'s rig deforms ("" for all of them)."""
    return obj.shapedeform.get(RIGGED_KEY, RIGGED)  # rigs bound before the key was kept used RIGGED


def keep_marks(obj):
    """Keep what bound ``obj``'s rig keeps on its layers, the marks of its rigged layers and,
    with Layers Apart, their islands, on the layers they were on when layers come or go; drop
    the marks no rig of its data reads.

    Ctrl+J of another grease pencil into this one merges layer attributes out of order (Blender
    4.5 by their place in the list, not their name; 5.0-5.2 put the joined layers' values
    first), which moved the marks onto joined layers, and brings the joined rig's marks, its
    rig gone with it. The layers' names and values are kept on the object: while the number of
    layers stays, they follow Blender's values (a layer renamed or moved); when it changes, the
    values are set again by name (a layer added, deleted or joined in), but for a layer of a
    new name that Blender's values, in step with the names elsewhere, give a value: a layer
    renamed in the same go (a script, or the extension off), as many of them as names are gone
    (a marked layer lost its mark, and stopped deforming)."""
    data = obj.data
    if data.library is not None or obj.library is not None:
        return
    _forget_stray_marks(obj)
    if not obj.shapedeform.is_bound:
        return
    settings = obj.shapedeform
    found = ((RIGGED_NAMES, _layer_attribute(data, settings.get(RIGGED_KEY), "BOOLEAN")),
             (LAYER_ISLANDS, _layer_attribute(data, ISLAND, "INT8")))
    kept = {key: attribute for key, attribute in found if attribute is not None}
    if not kept:
        return
    layers = [layer.name for layer in data.layers]
    values = {key: _layer_values(attribute, len(layers)) for key, attribute in kept.items()}
    if settings.get(RIGGED_COUNT, len(layers)) != len(layers):
        for key, attribute in kept.items():
            values[key] = _by_name(layers, values[key], _kept_values(settings, key))
            attribute.data.foreach_set("value", values[key])
        data.update_tag()
    _remember_layers(obj, layers, values.get(RIGGED_NAMES), values.get(LAYER_ISLANDS))


def _layer_attribute(data, name, data_type):
    """``data``'s LAYER attribute ``name`` of ``data_type``, or None."""
    attribute = data.attributes.get(name) if name else None
    return attribute if attribute is not None and attribute.domain == "LAYER" and attribute.data_type == data_type \
        else None


def _layer_values(attribute, count):
    """The values (count,) of LAYER ``attribute``: bool marks, or int32 islands."""
    values = np.zeros(count, dtype=bool if attribute.data_type == "BOOLEAN" else np.int32)
    attribute.data.foreach_get("value", values)
    return values


def _kept_values(settings, key):
    """{layer name: value} of the marks (``key`` RIGGED_NAMES) or islands (LAYER_ISLANDS) kept on
    ``settings`` as of the last update (an older version kept the marked names alone)."""
    names = settings[RIGGED_ALL].split("\n") if RIGGED_ALL in settings else None
    if key == LAYER_ISLANDS:
        return dict(zip(names, settings[LAYER_ISLANDS])) if names is not None and key in settings else {}
    named = set(settings.get(RIGGED_NAMES, "").split("\n")) - {""}
    return {name: name in named for name in names} if names is not None else dict.fromkeys(named, True)


def _by_name(layers, values, kept):
    """The values (l,) of ``layers`` (their names) by name from ``kept`` ({name: value}), where
    Blender's ``values`` (l,) are trusted only for layers of new names (see :func:`keep_marks`)."""
    known = np.isin(layers, list(kept))
    by_name = np.array([kept.get(layer, 0) for layer in layers], dtype=values.dtype)
    renamed = np.flatnonzero((values != 0) & ~known)
    gone = sum(1 for name, value in kept.items() if value and name not in layers)
    if np.array_equal(values[known], by_name[known]) and len(renamed) <= gone:
        by_name[renamed] = values[renamed]
    return by_name


def _remember_layers(obj, layers, marks=None, islands=None):
    """Keep the names of ``layers`` (in order), of those ``marks`` (l,) marks, and ``islands``
    (l,), on ``obj``."""
    settings = obj.shapedeform
    everyone = "\n".join(layers)
    if marks is not None:
        names = "\n".join(layer for layer, marked in zip(layers, marks) if marked)
        if settings.get(RIGGED_NAMES) != names:
            settings[RIGGED_NAMES] = names
    if islands is not None and list(settings.get(LAYER_ISLANDS, ())) != islands.tolist():
        settings[LAYER_ISLANDS] = islands.tolist()
    if settings.get(RIGGED_ALL) != everyone:
        settings[RIGGED_COUNT], settings[RIGGED_ALL] = len(layers), everyone


def _forget_stray_marks(obj):
    """Remove the layer marks in ``obj``'s data that no rig of the data reads."""
    data = obj.data
    own = _rigged_attribute(obj) if obj.shapedeform.is_bound else None
    marks = [a.name for a in data.attributes
             if a.name != own and (a.name == RIGGED or a.name.startswith(RIGGED + "."))]
    if not marks:  # on every update of a rigged drawing: the file's objects are not looked through
        return
    read = {_rigged_attribute(o) for o in rig_format.other_rigged_users(obj) if o.shapedeform.is_bound}
    for name in marks:
        if name not in read:
            data.attributes.remove(data.attributes[name])


def restore_legacy(obj):
    """Write an older version's saved rest points back (see :mod:`.sources`)."""
    # Every drawing's rest is read before any is written, so what is restored does not depend
    # on where in the list a lost drawing is.
    found, lost = [], []
    for name, number in bound_frames(obj):
        drawing = drawing_at(obj, name, number)
        attribute = drawing.attributes.get(REST_ATTRIBUTE) if drawing is not None else None
        if attribute is None:
            why = "its keyframe is gone" if drawing is None else f"its {REST_ATTRIBUTE} attribute is gone"
            lost.append(f"the drawing of layer '{name}' at frame {number} ({why})")
            continue
        found.append((drawing, read_vectors(attribute, len(attribute.data))))
    for drawing, rest in found:
        drawing.attributes.remove(drawing.attributes[REST_ATTRIBUTE])
        drawing.attributes["position"].data.foreach_set("vector", rest.ravel())
        drawing.tag_positions_changed()
    for key in (LEGACY_GP_LAYERS, LEGACY_GP_FRAMES):
        obj.shapedeform.pop(key, None)
    obj.data.update_tag()
    return lost


def selected(obj):
    """Layer-space rest positions (k, 3) of selected stroke points of the current drawings,
    of what Edit Mode edits: strokes on shown, unlocked layers (in shown, unlocked groups),
    drawn with shown materials that are unlocked (or on layers that ignore locked materials)."""
    chosen = [points for _, points in _selected_by_layer(obj)]
    return np.concatenate(chosen).astype(np.float64) if chosen else np.empty((0, 3))


def part_ranks(obj):
    """With Layers Apart, each cage point's layer's place among the drawing's layers now, the top
    one highest (review: layers reordered after Bind gave a handle to the layer drawn under)."""
    layers, points = rig_format.islands_of(obj.data), rig_format.islands_of(obj.shapedeform.cage.data)
    if layers is None or points is None or not len(points):
        return None
    place = np.full(max(int(layers.max(initial=0)), int(points.max())) + 1, -1)
    rigged = np.flatnonzero(layers > 0)
    place[layers[rigged]] = rigged
    return place[points]


def overlap_pin_notes(obj, rig, point, extent):
    """With Layers Apart each layer is drawn whole, in the drawing's order, whatever its height:
    a pin orders its own layer's strokes only (QA: an arm layer under the body stayed under it
    with a pin at 1)."""
    if rig_format.islands_of(obj.data) is None:
        return []
    return ["with Layers Apart the layers are drawn in their order whatever pins say: this pin orders the strokes "
            "of its own layer only (move a layer up or down to put it in front)"]


def selected_islands(obj):
    """Each selected point's island number (k,) int32, its layer's, in :func:`selected`'s order
    (0: not known, a layer added since binding), or None where the layers keep none (a rig
    without Layers Apart)."""
    islands = rig_format.islands_of(obj.data)
    if islands is None:
        return None
    chosen = [np.full(len(points), islands[index], np.int32) for index, points in _selected_by_layer(obj)]
    return np.concatenate(chosen) if chosen else np.empty(0, np.int32)


def _selected_by_layer(obj):
    """:func:`selected`'s points, layer by layer: [(the layer's index, (k, 3) float32)]."""
    slots = obj.material_slots
    hidden = np.array([_material_flag(slot, "hide") for slot in slots] + [False])
    locked = np.array([_material_flag(slot, "lock") for slot in slots] + [False])
    chosen = []
    for index, layer in enumerate(obj.data.layers):
        frame = layer.current_frame()
        if not _editable(layer) or frame is None or frame.drawing is None:
            continue
        drawing = frame.drawing
        points = _points(drawing)
        offsets = _stroke_offsets(drawing)
        strokes = len(offsets) - 1
        material = np.clip(_values(drawing, "material_index", strokes, np.int32, 0), 0, len(hidden) - 1)
        frozen = hidden[material] | (locked[material] & (not layer.ignore_locked_materials))
        chosen.append((index, points[_selection(drawing, len(points), offsets) & ~np.repeat(frozen, np.diff(offsets))]))
    return chosen


def _editable(layer):
    """Whether Edit Mode edits ``layer``: it and every group it is in are shown and unlocked."""
    node = layer
    while node is not None:
        if node.hide or node.lock:
            return False
        node = node.parent_group
    return True


def _material_flag(slot, flag):
    style = slot.material.grease_pencil if slot.material is not None else None
    return bool(style is not None and getattr(style, flag))


def _selection(drawing, count, offsets):
    """Which of a drawing's ``count`` points are selected (count,) bool; ``offsets`` (s + 1,)
    are its strokes' first points.

    Blender drops the ``.selection`` attribute when everything is selected (and a new drawing
    has none), keeps it per stroke in Stroke select mode, and per point otherwise.
    """
    attribute = drawing.attributes.get(".selection")
    if attribute is None:
        return np.ones(count, dtype=bool)
    values = np.zeros(len(attribute.data), dtype=np.float32 if attribute.data_type == "FLOAT" else bool)
    attribute.data.foreach_get("value", values)
    values = values > 0
    if attribute.domain == "CURVE":
        return np.repeat(values, np.diff(offsets)) if len(values) == len(offsets) - 1 else np.zeros(count, bool)
    return values if len(values) == count else np.zeros(count, dtype=bool)
