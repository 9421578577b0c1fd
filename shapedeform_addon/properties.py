# SPDX-License-Identifier: GPL-3.0-or-later
"""Settings and rig state stored on objects (``Object.shapedeform``), saved in the .blend.

Besides the properties declared here, a bound object keeps its rig's graph as ID properties of
``obj.shapedeform``; :mod:`.rig_format` says what is stored where.
"""

from functools import partial

import bpy
from bpy import props

from . import handles, rig


def _overridable(kind):
    """``kind`` of property, overridable: a library override of a rigged character keeps its
    rig's pointers remapped to the overridden cage and handles, and its settings editable."""
    return partial(kind, override={"LIBRARY_OVERRIDABLE"})


BoolProperty, CollectionProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty = (
    _overridable(kind) for kind in (props.BoolProperty, props.CollectionProperty, props.EnumProperty,
                                    props.FloatProperty, props.IntProperty, props.PointerProperty,
                                    props.StringProperty))


def _settings_changed(self, context):
    """Weights, area or folds changed: rebuild the deformer and pose again."""
    owner = self.id_data
    if isinstance(owner, bpy.types.Object) and self.is_bound:
        rig.invalidate(owner)
        rig.pose_safely(owner, context.evaluated_depsgraph_get())


def _iterations_changed(self, context):
    """An iteration budget changed: pose again with the same deformer."""
    owner = self.id_data
    if isinstance(owner, bpy.types.Object) and self.is_bound:
        rig.pose_safely(owner, context.evaluated_depsgraph_get())


def _pin_changed(self, context):
    """A pin's amount changed: pose its rig again (the reach is cached with the rig)."""
    owner = self.rig
    if isinstance(self.id_data, bpy.types.Object) and owner is not None and owner.shapedeform.is_bound:
        rig.pose_safely(owner, context.evaluated_depsgraph_get())


def _handle_picked(self, context):
    """A handle picked in the sidebar's list: its Empty selected and active, as a click in the
    Outliner makes it (in Object Mode; other modes keep their object). The add-on's own changes
    of the index go around this (:func:`.handles.set_active`)."""
    if context.mode != "OBJECT" or not 0 <= self.active_handle < len(self.handles):
        return
    empty = self.handles[self.active_handle].object
    view_layer = context.view_layer
    if empty is None or view_layer.objects.get(empty.name) != empty or not empty.visible_get(view_layer=view_layer):
        return
    for other in context.selected_objects:
        other.select_set(False)
    empty.select_set(True)
    view_layer.objects.active = empty


def _pin_reach_changed(self, context):
    """A pin's extent or stiffness changed: rebuild its rig's deformer and pose again."""
    owner = self.rig
    if owner is not None and owner.shapedeform.is_bound:
        rig.invalidate(owner)
        rig.pose_safely(owner, context.evaluated_depsgraph_get())
        handles.fit_pin_shapes(owner)


# Rig state and bind-time choices: keying them would animate nothing (or break the rig), so they
# do not offer keyframes; the energy's weights, budgets and pins' amounts do.
NOT_KEYABLE = set()

PIN_KINDS = [
    ("POSITION", "Position", "A handle: the shape follows where it is moved and turned"),
    ("OVERLAP", "Overlap", "Brings the shape near it in front of (or, negative, behind) other parts where they overlap"),
    ("STARCH", "Starch", "Stiffens the shape near it so that it bends less"),
]


class SHAPEDEFORM_PG_handle(bpy.types.PropertyGroup):
    """One handle of a rig: the Empty the animator moves."""

    object: PointerProperty(type=bpy.types.Object, name="Handle", description="The Empty that drives this handle")


class SHAPEDEFORM_PG_object(bpy.types.PropertyGroup):
    """Shape Deform settings and state of one object."""

    is_bound: BoolProperty(name="Bound", description="The object is rigged", default=False, options=NOT_KEYABLE)
    kind: StringProperty(name="Kind", description="What was rigged: MESH, IMAGE, CURVE, GREASEPENCIL or TEXT",
                          options=NOT_KEYABLE)
    handles: CollectionProperty(type=SHAPEDEFORM_PG_handle, name="Handles",
                                description="The rig's handles and pins, in the order they were added")
    active_handle: IntProperty(name="Active Handle", description="The handle the sidebar's list has picked",
                               default=0, min=0, options=NOT_KEYABLE, update=_handle_picked)
    handle_collection: PointerProperty(type=bpy.types.Collection, name="Handle Collection",
                                       description="The collection holding the rig's handles, pins and cage")
    handles_watched: FloatProperty(
        name="Handles Watched", description="Driven by the rig's handles and pins, so Blender evaluates them "
                                            "wherever this object is evaluated; its value is not used")
    original_data: PointerProperty(type=bpy.types.Mesh, name="Original Mesh",
                                   description="An image plane's quad, given back on unbind")
    rig: PointerProperty(type=bpy.types.Object, name="Rig",
                         description="On a handle or a cage: the bound object whose rig it belongs to")
    pin_kind: EnumProperty(name="Kind", description="What this handle of a rig does", items=PIN_KINDS,
                           default="POSITION", options=NOT_KEYABLE)
    in_front: FloatProperty(
        name="In Front", description="On an overlap pin: how far in front of other parts the shape near it is "
                                      "where they overlap (negative: behind); pins add up where they meet",
        default=1.0, soft_min=-3.0, soft_max=3.0, update=_pin_changed)
    stiffness: FloatProperty(
        name="Stiffness", description="On a starch pin: how much stiffer the shape near it is (0: as the rest of "
                                      "the shape; 10: ten times stiffer); pins add up where they meet",
        default=10.0, min=0.0, soft_max=100.0, update=_pin_reach_changed)
    extent: FloatProperty(
        name="Extent", description="On an overlap or starch pin: how far its influence reaches through the "
                                   "shape, as a fraction of the shape's size",
        default=0.25, min=0.001, max=2.0, subtype="FACTOR", update=_pin_reach_changed)
    cage: PointerProperty(type=bpy.types.Object, name="Cage",
                          description="The mesh of the rig's graph that the solver poses; the object's "
                                      "Shape Deform modifier maps every point through it")
    preserve_area: BoolProperty(name="Preserve Area", description="Keep the shape's total area",
                                default=False, update=_settings_changed)
    prevent_flips: BoolProperty(
        name="Prevent Folds",
        description="Push triangles squeezed below 40% of their area back open, so large bends "
                    "do not fold the shape over itself; poses that squeeze none are unchanged",
        default=True, update=_settings_changed)
    weight_laplacian: FloatProperty(name="Boundary Detail", description="Weight of the curve Laplacian term",
                                    default=1.0, min=0.0, soft_max=10.0, update=_settings_changed)
    weight_mvc: FloatProperty(name="Interior Shape", description="Weight of the mean value coordinates term",
                              default=1.0, min=0.0, soft_max=10.0, update=_settings_changed)
    weight_edge: FloatProperty(name="Edge Length", description="Weight of the edge length term",
                               default=1.0, min=0.0, soft_max=10.0, update=_settings_changed)
    iterations: IntProperty(name="Viewport", description="Most solver iterations per update while you work",
                            default=15, min=1, max=200, update=_iterations_changed)
    render_iterations: IntProperty(
        name="Render", description="Most solver iterations when baking, rendering or running without a "
                                   "window; solves that converge sooner stop sooner",
        default=30, min=1, max=200, update=_iterations_changed)
    graph_mode: EnumProperty(
        name="Graph", description="What the solver deforms",
        items=[("AUTO", "Automatic", "The mesh itself when it is small, an outline graph when it is dense"),
               ("OWN", "Mesh", "The mesh is its own graph: its boundary loops, vertices and edges"),
               ("OUTLINE", "Outline", "A graph built from the outline; every vertex is bound to it")],
        default="AUTO", options=NOT_KEYABLE)
    density: IntProperty(name="Graph Density", description="About how many interior points the built graph has",
                         default=300, min=20, max=5000, soft_max=2000, options=NOT_KEYABLE)
    region_size: FloatProperty(name="Handle Region",
                               description="Radius of the region a new handle holds, as a fraction of the shape's "
                                           "size (handles already added keep theirs)",
                               default=0.04, min=0.001, max=0.5, subtype='FACTOR', options=NOT_KEYABLE)
    layers: StringProperty(name="Layers", description="Grease pencil layers to rig, comma separated (empty: all)",
                            options=NOT_KEYABLE)
    layers_apart: BoolProperty(name="Layers Apart",
                               description="Grease pencil: each rigged layer is a part of its own, which moves apart "
                                           "from the others where they overlap (an arm on its own layer over the "
                                           "body); off, strokes that overlap join, whatever their layers",
                               default=False, options=NOT_KEYABLE)
    show_overlay: BoolProperty(name="Show Graph", description="Draw the graph and handle regions in the viewport",
                               default=False, options=NOT_KEYABLE)
    status: StringProperty(name="Status", description="Why the last update failed (empty when it worked)",
                            options=NOT_KEYABLE)


classes = (
    SHAPEDEFORM_PG_handle,
    SHAPEDEFORM_PG_object,
)

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    _register_classes()
    bpy.types.Object.shapedeform = PointerProperty(type=SHAPEDEFORM_PG_object, name="Shape Deform",
                                                   description="The object's Shape Deform rig and settings")


def unregister():
    del bpy.types.Object.shapedeform
    _unregister_classes()
