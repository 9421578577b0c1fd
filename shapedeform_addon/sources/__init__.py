# SPDX-License-Identifier: GPL-3.0-or-later
"""Where shapes come from and go back to: one module per kind of Blender object.

Each source module offers the same functions:

``prepare(obj, settings) -> Prepared``
    Read the rest geometry, find its plane and build the graph, changing nothing; raise
    :class:`RigError` with a message for the user when the object cannot be rigged.
``unbind(obj) -> list of str``
    Give back what binding changed on the object's data (an image plane's quad, a mesh's
    islands, a curve's Path Animation, the attribute of a drawing's rigged layers), for a rig's
    owner and for a duplicate that stops following a rig; what another rig of shared data still
    uses stays (``rig_format.other_rigged_users``). Called while the rig's cage and modifier are
    there. Returns what it could not give back, as phrases for a message.
``restore_legacy(obj) -> list of str``
    For a rig made by an older version, which wrote poses into the object's data: write the
    rest points it saved back exactly and delete them. Never fails for missing data, so such a
    rig can always be unbound: it gives back what it can and returns what it could not.
``selected(obj) -> (k, 3) float64``
    Local rest positions of the selected points (for a handle at each).

Where an overlap pin may order nothing, a source also offers ``overlap_pin_notes(obj, rig,
point, extent) -> list of str``, sentences for the status bar on a pin just added at graph
point ``point`` reaching ``extent``; :func:`overlap_pin_notes` gives none for the other sources.

Where parts of a rig overlap at rest in an order the object shows (a drawing's Layers Apart
layers), a source also offers ``part_ranks(obj) -> (n,) int or None``: each cage point's part's
place in that order, the top one highest; a handle added where parts lie level goes on the top
one (:func:`part_ranks` gives None for the other sources).

Where a source's points keep their island (a mesh that is its own graph in several islands),
it also offers ``selected_islands(obj) -> (k,) int or None``: each selected point's island number
(0 where not known), in ``selected``'s order, or None where the object keeps none. It tells
which part a handle at a selected point holds where islands overlap (a puppet's arm vertex on
a body vertex); :func:`selected_islands` gives None for the other sources.
"""

import types

from ..errors import RigError, with_article
from . import curve, grease_pencil, image_plane, mesh, text
from .prepared import Prepared

__all__ = ["RigError", "with_article", "type_name", "Prepared", "module_for", "kind_of", "selected_islands",
           "overlap_pin_notes", "part_ranks", "unbinding_module"]


def type_name(obj):
    """The object's type as Blender's interface names it, lower case ("empty", "text", "light probe")."""
    items = type(obj).bl_rna.properties["type"].enum_items
    return (items[obj.type].name if obj.type in items else obj.type.replace("_", " ")).lower()


def module_for(obj):
    """The source module of an object (bound or not); RigError for kinds we cannot rig.

    A bound mesh is what it was bound as (an image plane stays one after its quad became a
    cut-out, which no longer reads as an image plane); anything else is what its type says now
    (a text converted to a curve is a curve)."""
    stored = obj.shapedeform.kind if obj.shapedeform.is_bound else ""
    kind = stored if stored in {"MESH", "IMAGE"} and obj.type == "MESH" else kind_of(obj)
    return {"MESH": mesh, "IMAGE": image_plane, "CURVE": curve, "GREASEPENCIL": grease_pencil, "TEXT": text}[kind]


def unbinding_module(obj):
    """:func:`module_for` ``obj``, or, for an object converted since Bind to a kind no source
    rigs (Object > Convert > Curves makes hair curves), one that has nothing to give back: the
    rig alone goes (QA: Unbind refused, and left the cage and handles in the file)."""
    try:
        return module_for(obj)
    except RigError:
        return _CONVERTED


_CONVERTED = types.SimpleNamespace(unbind=lambda obj: [], restore_legacy=lambda obj: [])


def kind_of(obj):
    """What kind of shape an unbound object is: MESH, IMAGE, CURVE, GREASEPENCIL or TEXT."""
    if obj is None:
        raise RigError("No active object to rig")
    if obj.type == "MESH":
        return "IMAGE" if image_plane.is_image_plane(obj) else "MESH"
    if obj.type in {"CURVE", "GREASEPENCIL"}:
        return obj.type
    if obj.type == "FONT":
        return "TEXT"
    if obj.type == "EMPTY" and obj.empty_display_type == "IMAGE":
        raise RigError(f"'{obj.name}' is an image empty (a reference or background image), which has no "
                       "geometry to deform: add the picture as a plane (Add > Image > Mesh Plane) and bind that")
    raise RigError(f"'{obj.name}' is {with_article(type_name(obj))} object: Shape Deform rigs meshes, curves, "
                   "text, grease pencil and image planes")


def selected_islands(obj):
    """The island numbers (k,) of ``obj``'s selected points, where its source keeps them, else None
    (see the package's docstring; call in Object Mode)."""
    islands = getattr(module_for(obj), "selected_islands", None)
    return None if islands is None else islands(obj)


def overlap_pin_notes(obj, rig, point, extent):
    """Sentences saying where an overlap pin just added to ``obj``'s ``rig`` at graph point
    ``point``, reaching ``extent``, orders nothing (see the package's docstring)."""
    notes = getattr(module_for(obj), "overlap_pin_notes", None)
    return [] if notes is None else notes(obj, rig, point, extent)


def part_ranks(obj):
    """Each cage point's place in the order ``obj`` shows its overlapping parts in, or None (see
    the package's docstring)."""
    ranks = getattr(module_for(obj), "part_ranks", None)
    return None if ranks is None else ranks(obj)
