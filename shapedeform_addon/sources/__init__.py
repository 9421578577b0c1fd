# SPDX-License-Identifier: GPL-3.0-or-later
"""Where shapes come from and go back to: one module per kind of Blender object.

Each source module offers the same functions:

``prepare(obj, settings) -> Prepared``
    Read the rest geometry, find its plane and build the graph, changing nothing; raise
    :class:`RigError` with a message for the user when the object cannot be rigged.
``read_rest(obj) -> (p, 3) float64``
    The rest points saved at bind time, in the order :func:`write` takes.
``write(obj, points)``
    Write (p, 3) float32 points back, one ``foreach_set`` per array.
``restore(obj) -> list of str``
    Write the rest points back exactly and delete the saved rest data. Never fails for missing
    data, so a broken rig can always be unbound: it gives back what it can and returns what it
    could not, as phrases for a message ("the drawing of layer 'Ink' at frame 3 (...)").
"""

from dataclasses import dataclass, field
from typing import Callable

import numpy as np


class RigError(Exception):
    """An object cannot be rigged (or its rig cannot run); the message is for the user."""


def with_article(noun):
    """``noun`` after "a" or "an", for messages ("an empty", "a camera").

    By its first letter: the nouns these messages use (Blender's object types and the rig kinds)
    have no silent or long-vowel exceptions such as "hour" or "unit".
    """
    return f"{'an' if noun[:1].lower() in 'aeiou' else 'a'} {noun}"


def type_name(obj):
    """The object's type as Blender's interface names it, lower case ("empty", "text", "light probe")."""
    items = type(obj).bl_rna.properties["type"].enum_items
    return (items[obj.type].name if obj.type in items else obj.type.replace("_", " ")).lower()


@dataclass
class Prepared:
    """What binding an object needs, computed before anything is changed.

    Attributes
    ----------
    rest : (p, 3) float32 ndarray
        The points that follow the deformation, as the object stores them.
    plane : solver.rigging.Plane
    graph : solver.Graph
    own_graph : bool
        The points are the graph's points (no binding needed).
    commit : callable(obj)
        Makes the changes binding needs (store rest data, replace an image quad).
    """

    rest: np.ndarray
    plane: object
    graph: object
    own_graph: bool
    commit: Callable = field(default=lambda obj: None)


def module_for(obj):
    """The source module of an object (bound or not); RigError for kinds we cannot rig."""
    from . import curve, grease_pencil, image_plane, mesh

    kind = obj.shapedeform.kind if obj.shapedeform.is_bound else kind_of(obj)
    return {"MESH": mesh, "IMAGE": image_plane, "CURVE": curve, "GREASEPENCIL": grease_pencil}[kind]


def kind_of(obj):
    """What kind of shape an unbound object is: MESH, IMAGE, CURVE or GREASEPENCIL."""
    from . import image_plane

    if obj is None:
        raise RigError("No active object to rig")
    if obj.type == "MESH":
        return "IMAGE" if image_plane.is_image_plane(obj) else "MESH"
    if obj.type in {"CURVE", "GREASEPENCIL"}:
        return obj.type
    raise RigError(f"'{obj.name}' is {with_article(type_name(obj))} object: Shape Deform rigs meshes, curves, "
                   "grease pencil and image planes")
