# SPDX-License-Identifier: GPL-3.0-or-later
"""Curves: Bezier, NURBS and poly splines, several of them (text converted to a curve has holes).

Closed splines bound the shape, and so does a silhouette swept around open splines where they lie
outside the closed ones (a tail beside a body, or a curve of open splines alone). Control points
and both Bezier handles of every spline are bound to its graph, so an open spline drawn inside a
closed one (a detail line) follows the part it lies in. Points are ordered spline after spline:
a Bezier spline gives its control points, then left handles, then right handles; a poly or NURBS
spline its points. The curve is never written: its Shape Deform modifier maps control points
and handles (a filled, bevelled or text curve reaches the modifier as its tessellated mesh,
which is mapped the same way).

Path Animation (on by default for Blender's Add > Curve objects) carries a curve's children
along its path, so a child would depend on the curve's geometry, which the rig makes. Only
children parented to the object ride the path (and a Guide force field on it needs it; Follow
Path, Clamp To, the Curve modifier and text on a curve have Blender compute the path anyway), so
Bind turns it off when nothing uses it, marking the data (``rig_format.turn_path_off``), and
Unbind turns it on again once no rig made as the children of an object with this data is left;
the handles and cage are then the curve's children. Where something uses it, they follow the
curve by constraints instead.

``sd_rest`` (an ID property of the curve data) is where an older version kept the rest points
while it wrote poses into the curve; :func:`restore_legacy` gives them back.
"""

import bpy
import numpy as np

from ...solver.outline import outline_graph
from ...solver.rigging.outline import refine_level, sample_bezier, sample_nurbs, with_area
from ...solver.rigging.plane import fit_plane
from ...solver.rigging.silhouette import stroke_silhouette
from ...solver.wording import by_count
from .. import compat, rig_format
from ..errors import RigError
from ..nodes import REFINE_INPUT, REFINE_MOST
from .mesh import edges, positions
from .prepared import Prepared

REST_PROPERTY = "sd_rest"
# Sweep radius around open splines, as a fraction of the curve's size (or the bevel depth when
# that is larger).
SWEEP_FRACTION = 0.02


def _vectors(collection, name, width):
    flat = np.empty(len(collection) * width, dtype=np.float32)
    collection.foreach_get(name, flat)
    return flat.reshape(-1, width)


def points(curve):
    """All control points and handles, (p, 3) float32, in the rig's order."""
    parts = [np.empty((0, 3), np.float32)]
    for spline in curve.splines:
        if spline.type == "BEZIER":
            bezier = spline.bezier_points
            parts += [_vectors(bezier, name, 3) for name in ("co", "handle_left", "handle_right")]
        else:
            parts.append(_vectors(spline.points, "co", 4)[:, :3])
    return np.concatenate(parts)


def _rings_and_strokes(curve, flat):
    """Closed splines as rings, open ones as polylines, in plane coordinates, as Blender draws them."""
    rings, strokes, start = [], [], 0
    for spline in curve.splines:
        if spline.type == "BEZIER":
            k = len(spline.bezier_points)
            co, left, right = flat[start:start + k], flat[start + k:start + 2 * k], flat[start + 2 * k:start + 3 * k]
            line = sample_bezier(co, left, right, spline.use_cyclic_u, spline.resolution_u)
            start += 3 * k
        else:
            k = len(spline.points)
            line = flat[start:start + k]
            if spline.type == "NURBS":
                weights = _vectors(spline.points, "co", 4)[:, 3]
                line = sample_nurbs(line, weights, spline.order_u, spline.use_cyclic_u, spline.use_endpoint_u,
                                    spline.use_bezier_u, spline.resolution_u, compat.NURBS_SAMPLED_PER_SPAN)
            start += k
        if k < 2:
            continue  # a lone point: Blender draws nothing of it (a Bezier one looped round its handles, QA)
        if spline.use_cyclic_u:
            rings.append(line)
        else:
            strokes.append(line)
    return rings, strokes


def prepare(obj, settings):
    """Read the object's rest shape and build its graph, changing nothing (see :mod:`.sources`)."""
    prepared = prepare_splines(obj, obj.data, settings)
    if obj.data.use_path:
        users = path_users(obj)
        if users:
            prepared.advice = (f"Path Animation stays on ({'; '.join(users)}), so the handles follow the curve by "
                               "constraints: move the curve without its handles (moved with it, they move twice)")
        else:
            prepared.commit = lambda o: rig_format.turn_path_off(o.data)
            prepared.advice = "turned Path Animation off, as nothing rides the curve's path (Unbind turns it on again)"
    return prepared


def path_users(obj):
    """What needs the Path Animation of curve ``obj``'s data, as phrases (empty when nothing).

    Objects parented to an object with this data ride its path, as do objects and bones with a
    Follow Path or Clamp To constraint aimed at one (QA: without it they jumped to the curve's
    origin), a Guide force field on one follows it, an animated Evaluation Time is meant to move
    something along it, and data of a library cannot be changed here. The curve's own rig's
    handles and cage are not counted.
    """
    data = obj.data
    if data.library is not None:
        return [f"the curve's data comes from the library '{data.library.name}'"]
    sharing = [o for o in bpy.data.objects if o.data == data]
    # Only the curve's own rig is left out: another rig's handle may ride its path (review).
    riders = [child.name for o in sharing for child in o.children
              if child.parent_type == "OBJECT" and child.shapedeform.rig not in sharing]
    riders += [o.name for o in bpy.data.objects if o.name not in riders and o.shapedeform.rig not in sharing
               and any(c.type in PATH_CONSTRAINTS and c.target in sharing for c in _constraints(o))]
    guides = [o.name for o in sharing if o.field is not None and o.field.type == "GUIDE"]
    found = [f"{', '.join(map(repr, riders))} {by_count(len(riders), 'rides', 'ride')} the path"] if riders else []
    found += [f"a Guide force field on {', '.join(map(repr, guides))}"] if guides else []
    found += ["the curve's Evaluation Time is animated"] if compat.is_animated(data, "eval_time") else []
    return found


# Constraints that place their owner along a curve's path, which Path Animation makes.
PATH_CONSTRAINTS = {"FOLLOW_PATH", "CLAMP_TO"}


def _constraints(obj):
    """``obj``'s constraints and its bones'."""
    bones = obj.pose.bones if obj.pose is not None else ()
    return [*obj.constraints, *(c for bone in bones for c in bone.constraints)]


def prepare_splines(obj, curve, settings):
    """The plane and graph of ``curve``'s splines (a curve's own data, or a text's outlines)."""
    rest = points(curve)
    if len(rest) == 0:
        raise RigError(f"'{obj.name}' has no control points")
    try:
        # A straight open curve lies in many planes: the one of a 2D curve, its local XY.
        plane = fit_plane(rest, line_normal=(0.0, 0.0, 1.0))
        flat = plane.to_2d(rest)
        rings, strokes = _rings_and_strokes(curve, flat)
        if not rings and not strokes:
            raise RigError(f"'{obj.name}' cannot be rigged: each of its splines has a single point, of which "
                           "Blender draws no line")
        # A closed spline round no area (its points on one line) is left out; when all are and
        # no spline is open, the graph refuses them.
        areas = with_area(rings)
        if strokes:
            size = float(np.linalg.norm(np.ptp(flat, axis=0)))
            radius = max(curve.bevel_depth, SWEEP_FRACTION * size)
            offsets = np.concatenate([[0], np.cumsum([len(s) for s in strokes])])
            rings = stroke_silhouette(np.concatenate(strokes), offsets, np.full(offsets[-1], radius), areas=areas)
        elif not areas:
            splines = by_count(len(rings), "spline encloses", "splines enclose")
            raise RigError(f"'{obj.name}' cannot be rigged: its closed {splines} no area (the points of each lie on "
                           "one line, or at fewer than three places)")
        else:
            rings = areas
        graph = outline_graph(rings, settings.density)
    except ValueError as err:
        raise RigError(f"'{obj.name}' cannot be rigged: {err}") from None

    return Prepared(plane, graph, modifier_inputs={REFINE_INPUT: _fill_refinement(obj, plane, graph)})


def _fill_refinement(obj, plane, graph):
    """Refine for the faces ``obj`` reaches its modifier with (a fill, a bevel; 0 when none)."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    fill = evaluated.to_mesh()
    try:
        return refine_level(plane.to_2d(positions(fill)), edges(fill), len(fill.polygons), graph.spacing, REFINE_MOST)
    finally:
        evaluated.to_mesh_clear()


def unbind(obj):
    """Give back what binding changed; what could not be, as phrases (see :mod:`.sources`).

    Path Animation comes back on where Bind turned it off, unless another rig made as the
    children of an object with this data (not following it by constraints) still needs it off.
    """
    if not any(not rig_format.follows_by_constraint(other) for other in rig_format.other_rigged_users(obj)):
        rig_format.turn_path_back_on(obj.data)
    return []


def _write(obj, values):
    curve = obj.data
    start = 0
    for spline in curve.splines:
        if spline.type == "BEZIER":
            bezier = spline.bezier_points
            k = len(bezier)
            for name in ("co", "handle_left", "handle_right"):
                bezier.foreach_set(name, np.ascontiguousarray(values[start:start + k]).ravel())
                start += k
        else:
            k = len(spline.points)
            co = _vectors(spline.points, "co", 4)
            co[:, :3] = values[start:start + k]
            spline.points.foreach_set("co", co.ravel())
            start += k
    curve.update_tag()


def restore_legacy(obj):
    """Write an older version's saved rest points back (see :mod:`.sources`)."""
    values = obj.data.get(REST_PROPERTY)
    if values is None:
        return [f"the rest shape (property {REST_PROPERTY} is gone; the points stay where they are)"]
    rest = np.asarray(values, dtype=np.float64).reshape(-1, 3)
    if len(rest) != len(points(obj.data)):
        # Points were added or deleted since binding: which rest point is whose is unknown.
        return ["the rest shape (control points were added or deleted since binding; "
                "they stay where they are)"]
    _write(obj, rest.astype(np.float32))
    del obj.data[REST_PROPERTY]
    return []


def selected(obj):
    """Local rest positions (k, 3) of selected control points."""
    chosen = [np.empty((0, 3))]
    for spline in obj.data.splines:
        if spline.type == "BEZIER":
            bezier = spline.bezier_points
            mask = np.empty(len(bezier), dtype=bool)
            bezier.foreach_get("select_control_point", mask)
            chosen.append(_vectors(bezier, "co", 3)[mask])
        else:
            mask = np.empty(len(spline.points), dtype=bool)
            spline.points.foreach_get("select", mask)
            chosen.append(_vectors(spline.points, "co", 4)[mask, :3])
    return np.concatenate(chosen).astype(np.float64)
