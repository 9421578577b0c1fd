# SPDX-License-Identifier: GPL-3.0-or-later
"""Dragging handles in the 3D viewport: the modal operator and its per-event logic.

``invoke`` only runs with a window, so everything an event does lives in :class:`DragSession`
(plain Python, driven by any object with ``type``, ``value``, ``mouse_x``, ``mouse_y`` and
``ctrl``) and in the functions :func:`begin`, :func:`move`, :func:`confirm` and :func:`cancel`,
which take a mouse *ray* and are usable from scripts and tests.

How the mouse maps to the rig: the mouse ray (from ``bpy_extras.view3d_utils``) meets the rig's
plane in world space; the handle nearest to that first hit is grabbed, and afterwards it moves
by exactly as much as the hit point does, in the plane, so it never jumps to the cursor.
"""

import bpy
import numpy as np
from bpy_extras import view3d_utils

from ..solver.rigging.drag import above_every_layer, nearest, parent_offset, ray_plane, transform_points, world_plane
from . import autokey, handles, rig, rig_format
from .errors import RigError, poll_reason

HEADER = {
    False: "Shape Deform drag: click a handle to grab it (Ctrl+click: pin the shape there) | "
           "Right click / Esc: cancel",
    True: "Shape Deform drag: move the mouse | Click / Enter: confirm | Right click / Esc: cancel",
}

# Events left to the viewport while dragging, so the animator can still orbit, pan and zoom.
NAVIGATION = {"MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "TRACKPADPAN", "TRACKPADZOOM",
              "MOUSEROTATE", "MOUSESMARTZOOM", "NDOF_MOTION"}


def mouse_ray(region, region_3d, mouse):
    """World ray (origin, direction) under ``mouse`` (x, y in region pixels)."""
    origin = view3d_utils.region_2d_to_origin_3d(region, region_3d, mouse)
    direction = view3d_utils.region_2d_to_vector_3d(region, region_3d, mouse)
    return np.array(origin, dtype=np.float64), np.array(direction, dtype=np.float64)


def _matrix(m):
    return np.array(m, dtype=np.float64)


class DragState:
    """One grab: what is dragged, where it started, and what to put back on cancel.

    Attributes
    ----------
    obj : bpy.types.Object
        The rigged object.
    handle : bpy.types.Object
        The Empty being moved.
    pinned : bool
        ``handle`` is a pin made for this drag (removed on cancel).
    active_handle : int
        The handle list's active item before the grab (a pin made for it becomes the active
        one, and the active object in place of a handle of the rig; cancelling gives both
        back as they were).
    """

    def __init__(self, obj, handle, pinned, plane, hit, collection_was_missing, active_handle):
        self.obj = obj
        self.handle = handle
        self.pinned = pinned
        self.active_handle = active_handle
        self.plane_origin, self.plane_normal = plane
        self.start_hit = hit
        self.start_location = tuple(handle.location)  # floats read from float32: restored bit for bit
        self.collection_was_missing = collection_was_missing
        self.moved = False
        self.replaced_active = None  # (object, was selected): the active handle a pin took over from


def _plane(obj):
    """The rig's plane in world space, (origin, unit normal)."""
    plane = rig.get(obj).plane
    try:
        return world_plane(rig_format.rig_space(obj), plane.origin, plane.normal)
    except ValueError as err:
        raise RigError(f"'{obj.name}': {err}") from None


def begin(context, obj, ray, pin=False):
    """Grab the handle of ``obj`` nearest to where ``ray`` meets its plane.

    Parameters
    ----------
    context : bpy.types.Context
    obj : bpy.types.Object
        A bound object.
    ray : (origin, direction)
        World-space mouse ray.
    pin : bool
        Instead of a handle, grab the nearest point of the shape: a new handle (a pin) is
        made there for this drag; confirming keeps it, cancelling removes it.

    Returns
    -------
    DragState

    Raises
    ------
    RigError
        Not bound, baked or linked (:func:`_refusal`), the ray misses the plane (edge-on view),
        no handle to grab, or the pin could not be made; nothing was changed.
    """
    if _refusal(obj):
        raise RigError(_refusal(obj))
    plane = _plane(obj)
    hit = ray_plane(*ray, *plane)
    if hit is None:
        raise RigError(f"The view looks at '{obj.name}' edge-on: turn the view to drag on its plane")
    settings = obj.shapedeform
    if pin:
        shape = transform_points(rig_format.rig_space(obj), rig.get(obj).shown)
        if len(shape) == 0:
            raise RigError(f"'{obj.name}' has no points to pin")
        missing, active = settings.handle_collection is None, settings.active_handle
        # Where the pose overlaps itself, on the part in front (the rig's front, which renders
        # see): the hit lies on the plane, as near a part left there, under the others, as to
        # the one in front.
        handle = handles.add(obj, tuple(above_every_layer(hit, shape, plane[1])), snap=True)
        state = DragState(obj, handle, True, plane, hit, missing, active)
        _take_over_active_handle(context.view_layer, state)
        context.view_layer.update()
        return state
    # A handle deleted in the viewport lingers as an orphan (in no scene): never grab it. Pins
    # pull nothing and ride on the cage: dragging one would only pull it off the shape.
    candidates = [item.object for item in rig_format.present_items(obj)
                  if item.object.shapedeform.pin_kind == "POSITION"]
    if not candidates:
        raise RigError(f"'{obj.name}' has no handles: add one, or Ctrl+click to pin the shape")
    # As G: a handle hidden, in a hidden collection, or unselectable is not grabbed (QA).
    candidates = [h for h in candidates if h.visible_get(view_layer=context.view_layer) and not h.hide_select]
    if not candidates:
        raise RigError(f"'{obj.name}' shows no handle that can be selected: unhide its handles (Alt+H), or "
                       "Ctrl+click to pin the shape")
    centres = np.array([_matrix(h.matrix_world)[:3, 3] for h in candidates]).reshape(-1, 3)
    return DragState(obj, candidates[nearest(centres, hit)], False, plane, hit, False, settings.active_handle)


def _take_over_active_handle(view_layer, state):
    """Where the active object is a handle of the rig, make the new pin the active object in
    its place, as "+" makes a handle: the handle list follows the active object (QA: it went
    back to the old handle, and "-" removed that one instead of the pin)."""
    active = view_layer.objects.active
    if active is None or active.type != "EMPTY" or handles.rig_of(active) != state.obj:
        return
    state.replaced_active = (active, active.select_get(view_layer=view_layer))
    active.select_set(False, view_layer=view_layer)
    state.handle.select_set(True, view_layer=view_layer)
    view_layer.objects.active = state.handle


def move(context, state, ray):
    """Move the grabbed handle by how far the ray's hit on the plane moved; pose the shape.

    Returns
    -------
    bool
        False when the ray misses the plane (the handle stays where it was).
    """
    hit = ray_plane(*ray, state.plane_origin, state.plane_normal)
    if hit is None:
        return False
    handle = state.handle
    # A handle's location lives in its parent's space (handles are parented to their rig).
    offset = parent_offset(handles.parent_space(handle), hit - state.start_hit)
    offset = np.where(tuple(handle.lock_location), 0.0, offset)  # locked axes stay, as G keeps them (QA)
    handle.location = tuple(np.asarray(state.start_location) + offset)
    state.moved = True
    # The depsgraph handler poses the shape when it sees the handle's transform change.
    context.view_layer.update()
    return True


def confirm(context, state):
    """Keep the drag; with auto-keying on, key the moved handle as Blender's own auto-keying
    keys an object moved with G.

    Returns
    -------
    list of bpy.types.Object
        The handles that were keyed.
    """
    tools = context.scene.tool_settings
    if not (tools.use_keyframe_insert_auto and (state.moved or state.pinned)):
        return []
    return [state.handle] if autokey.key_moved(context, state.handle) else []


def cancel(context, state):
    """Put everything back as it was before the grab: handle, pin, the handle list's active
    item, and the shape's points."""
    obj = state.obj
    if state.pinned:
        if state.replaced_active is not None:
            active, selected = state.replaced_active
            context.view_layer.objects.active = active
            active.select_set(selected, view_layer=context.view_layer)
        handles.remove(obj, {state.handle})
        handles.set_active(obj.shapedeform, state.active_handle)
        collection = obj.shapedeform.handle_collection
        if state.collection_was_missing and collection is not None and not collection.all_objects:
            obj.shapedeform.handle_collection = None
            bpy.data.collections.remove(collection)
    else:
        state.handle.location = state.start_location
    context.view_layer.update()
    # The solve depends only on the handles, so posing again gives back the exact shape.
    rig.pose_safely(obj, context.evaluated_depsgraph_get())


class DragSession:
    """The state of one run of the modal operator, driven by events.

    Parameters
    ----------
    obj : bpy.types.Object
        The rig to drag on.
    region, region_3d
        The viewport's WINDOW region (``x``, ``y``, ``width``, ``height``) and its
        ``RegionView3D``; stand-ins with the same attributes work.
    """

    def __init__(self, obj, region, region_3d):
        self.obj = obj
        self.region = region
        self.region_3d = region_3d
        self.state = None
        self.message = ""

    def header(self):
        return HEADER[self.state is not None]

    def ray(self, event):
        mouse = (event.mouse_x - self.region.x, event.mouse_y - self.region.y)
        return mouse_ray(self.region, self.region_3d, mouse)

    def event(self, context, event):
        """Act on one event; returns the operator's result set."""
        self.message = ""
        kind, value = event.type, event.value
        if kind in {"ESC", "RIGHTMOUSE"} and value == "PRESS":
            if self.state is not None:
                cancel(context, self.state)
                self.state = None
            return {"CANCELLED"}
        if kind in {"RET", "NUMPAD_ENTER"} and value == "PRESS":
            return self._confirm(context) if self.state is not None else {"CANCELLED"}
        if kind == "LEFTMOUSE":
            if self.state is None and value == "PRESS":
                try:
                    self.state = begin(context, self.obj, self.ray(event), pin=bool(event.ctrl))
                except RigError as err:
                    self.message = str(err)
                return {"RUNNING_MODAL"}
            if self.state is not None and (value == "PRESS" or (value == "RELEASE" and self.state.moved)):
                return self._confirm(context)  # click-move-click, or press-drag-release
            return {"RUNNING_MODAL"}
        if kind in {"MOUSEMOVE", "INBETWEEN_MOUSEMOVE"}:
            if self.state is not None:
                try:
                    move(context, self.state, self.ray(event))
                except ValueError as err:
                    self.message = str(err)
            return {"RUNNING_MODAL"}
        if kind in NAVIGATION:
            return {"PASS_THROUGH"}
        return {"RUNNING_MODAL"}

    def _confirm(self, context):
        keyed = confirm(context, self.state)
        if keyed:
            self.message = f"Keyed {', '.join(h.name for h in keyed)}"
        self.state = None
        return {"FINISHED"}


def _window_region(context):
    """The 3D viewport's main region and its RegionView3D (the sidebar has neither)."""
    area = context.area
    if area is None or area.type != "VIEW_3D":
        return None, None
    region = context.region
    if region is None or region.type != "WINDOW":
        region = next((r for r in area.regions if r.type == "WINDOW"), None)
    return region, area.spaces.active.region_3d


def _refusal(obj):
    """Why the rig ``obj`` (from :func:`~.rig_format.active_rig`) cannot be dragged, or ""."""
    if obj is None or not obj.shapedeform.is_bound:
        return "Select a bound object or one of its handles to drag"
    try:
        rig_format.require_posable(obj, "drag its handles")
    except RigError as err:
        return str(err)
    if rig_format.is_baked(obj):
        return f"'{obj.name}' plays its bake: clear the bake (Clear Bake) to pose it live"
    return ""


class SHAPEDEFORM_OT_drag(bpy.types.Operator):
    """Drag a handle of the active rig with the mouse (Ctrl+click pins the shape anywhere)"""

    bl_idname = "shapedeform.drag"
    bl_label = "Drag Handle"
    bl_options = {"REGISTER", "UNDO", "BLOCKING"}

    @classmethod
    def poll(cls, context):
        return poll_reason(cls, _refusal(rig_format.active_rig(context)))

    def invoke(self, context, event):
        obj = rig_format.active_rig(context)
        if _refusal(obj):
            self.report({"ERROR"}, _refusal(obj))
            return {"CANCELLED"}
        region, region_3d = _window_region(context)
        if region is None or region_3d is None:
            self.report({"ERROR"}, "Drag works in a 3D viewport")
            return {"CANCELLED"}
        self.area = context.area
        self.session = DragSession(obj, region, region_3d)
        self.area.header_text_set(self.session.header())
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        session = self.session
        result = session.event(context, event)
        if session.message:
            self.report({"WARNING"} if "FINISHED" not in result else {"INFO"}, session.message)
        area = getattr(self, "area", None)
        if area is not None:
            area.header_text_set(None if result & {"FINISHED", "CANCELLED"} else session.header())
            area.tag_redraw()
        return result

    def execute(self, context):
        # Reached only without a window ('INVOKE_DEFAULT' headless): a drag needs the mouse.
        self.report({"ERROR"}, "Drag needs the mouse in a 3D viewport; from scripts, move the handle Empties")
        return {"CANCELLED"}


classes = (SHAPEDEFORM_OT_drag,)

register, unregister = bpy.utils.register_classes_factory(classes)
