# SPDX-License-Identifier: GPL-3.0-or-later
"""The saved rig format: everything a rig keeps in the .blend, read and written here only.

A rig never changes the shape of the object it deforms (an image plane's quad is swapped for a
cut-out mesh the rig makes, and given back on unbind; a mesh that is its own graph in several
islands gets its vertices' islands, the hidden point attribute ``nodes.ISLAND``, removed on
unbind by the last rig of the mesh: :func:`other_rigged_users`). What it keeps:

On the bound object (the rig's *owner*), ``obj.shapedeform``:
    ``is_bound``, ``kind``, the settings (:mod:`.properties`), ``cage``, ``handles`` (each item:
    the Empty, and as ID properties ``indices``, the graph points it owns, and ``offsets``,
    those points in the handle's frame when it was added; a pin's item has ``point``, the graph
    point it is bound to, and its Empty, vertex-parented to that point of the cage, says its
    ``pin_kind`` and amounts), and as ID properties the plane
    (``plane``, 12 numbers) and the graph (``graph_points``, ``graph_edges``, ``graph_loops``
    with ``graph_loop_sizes``, ``graph_triangles``), stored rather than rebuilt so that a file
    opens with exactly the graph it was rigged with; for grease pencil ``rigged_attribute``,
    the name of the LAYER attribute marking the layers it deforms (one per rig, as objects
    sharing their data may rig different layers; "" when it deforms them all); for an image
    plane ``cutout_points``, the cut-out's vertices as bind made them (unbind tells from them
    whether the cut-out was edited).
On an image plane's quad (kept as the bound plane's ``original_data``), ``shapedeform_cutout``:
    the names of the cut-outs it is kept for (:func:`quad_cutouts`), those Bind made of it and
    shared by linked duplicates; a duplicate showing another cut-out gets a quad of its own
    (:func:`.sources.image_plane.own_quad`).
On a curve's data, ``shapedeform_path_off``: Bind turned its Path Animation off (nothing rode
    the path, and the rig's children would have; :func:`turn_path_off`); Unbind turns it on
    again (:func:`turn_path_back_on`).
On a scene that shows rigs, ``shapedeform_lock_interface``: True where Bind, or the sweep of
    scenes that show rigs they did not bind, turned its Render > Lock Interface on (frame
    handlers pose rigs while a render reads the scene: :func:`lock_interface`), False where the
    lock was the user's own; once the scene shows no rig (an Unbind, the character removed from
    a shot) the mark goes, and a lock we turned on with it (:func:`unlock_interface`).
The cage, a mesh object parented to the owner (or, on a curve whose Path Animation stayed on,
    copying its transform: :func:`follows_by_constraint`) and hidden:
    the graph's triangles, its positions the current pose in *rig space* (the owner's local
    space when it was bound), its point attribute ``sd_rest`` the rest (and ``nodes.ISLAND``
    each point's island number (:func:`island_numbers`), where the owner's vertices have theirs,
    or from 1 where its grease pencil's layers have theirs: Layers Apart), ``shapedeform.rig``
    the owner. A bake is shape keys on its mesh, its Key and action marked ``shapedeform_bake``
    (:mod:`.bake`; a copy of the mesh for a rig of its own has an action of its own:
    :func:`copy_cage_mesh`), the Key's ``shapedeform_baked_from`` a digest of what the bake was
    made from and ``shapedeform_baked_from_numbers`` its numbers (:func:`bake_source`; none in
    files from before them); the mesh's ``shapedeform_cage`` names the owner's cage object it
    belongs to (:func:`.duplicates.own_cage_mesh`). In a library override of a rigged character the cage's mesh is a local
    copy of the library's, made the first time the rig poses, bakes or clears a bake
    (:func:`own_mesh`), and again when the library's rig was bound anew
    (:func:`follow_library_cage`).
Every object the rig deforms (the owner, and duplicates of it):
    a Geometry Nodes modifier with the group of :mod:`.nodes`, whose inputs name its cage,
    the rig's handle collection and the layer attribute.

A duplicate of the owner (Shift+D, Alt+D) copies its settings and modifier: it *follows* the
owner's rig (the same handles; a cage object of its own, in no collection, parented to it and
sharing the rig's cage mesh: :func:`.duplicates.follow`) and is never posed on its own. Unbinding
the owner releases it first (:func:`.duplicates.release_followers`).
"""

import random

import bpy
import numpy as np

from .. import solver
from ..solver.rigging.plane import Plane, affine_inverse
from . import compat, nodes
from .errors import RigError

GRAPH_KEYS = ("plane", "graph_points", "graph_edges", "graph_loops", "graph_loop_sizes", "graph_triangles",
              "graph_spacing")
MODIFIER_NAME = "Shape Deform"
BAKED = "baked"  # on the owner's settings: [start, end, step] of the bake that plays (as BAKE_FRAMES)
BAKE_FRAMES = "shapedeform_baked_frames"  # on a bake's Key: [start, end, step] of the frames it holds
BAKE_MARK = "shapedeform_bake"  # ID property on the data-blocks a bake created
BAKE_IN_TIME = "shapedeform_bake_in_time"  # on a bake's Key: absolute keys, played by its Evaluation Time
BAKE_SOURCE = "shapedeform_baked_from"  # on a bake's Key: a digest of what it was made from (.bake_source.fingerprint)
BAKE_SOURCE_NUMBERS = "shapedeform_baked_from_numbers"  # ... and its numbers, compared within a tolerance
# On the owner's settings: the name of the attribute marking the grease-pencil layers its rig
# deforms ("" for all of them); the modifier is given the same name.
RIGGED_KEY = "rigged_attribute"
# ... and the names of those layers, one per line, as of when it had RIGGED_COUNT layers in all,
# named RIGGED_ALL (``sources.grease_pencil.keep_marks`` puts the marks back on them after Ctrl+J).
RIGGED_NAMES, RIGGED_COUNT, RIGGED_ALL = "rigged_layers", "rigged_layer_count", "all_layers"
# ... and with Layers Apart each of those layers' island, as the layer attribute ``nodes.ISLAND``
# (a byte) had it.
LAYER_ISLANDS = "layer_islands"
CUTOUT_KEY = "cutout_points"  # on an image plane's settings: the cut-out's vertices as bind made them
CUTOUT_ATTRIBUTES = "cutout_attributes"  # ... and its attributes (UV maps with a digest of their UVs)
QUAD_STAMP = "shapedeform_cutout"  # on an image plane's rest quad: the cut-outs it is kept for
HANDLE_INDICES = "indices"  # on a handle's item: the graph points it owns
HANDLE_OFFSETS = "offsets"  # on a handle's item: those points in its frame when it was added
PIN_POINT = "point"  # on a pin's handle item: the graph point it is bound to
CAGE_STAMP = "shapedeform_cage"  # on a cage's mesh: the owner's cage object it belongs to
PATH_TURNED_OFF = "shapedeform_path_off"  # on a curve's data: Bind turned its Path Animation off
INTERFACE_LOCKED = "shapedeform_lock_interface"  # on a scene showing rigs: True where we turned its lock on
UNSETTLED = "shapedeform_unsettled"  # on a cage's mesh: its pose is a Viewport solve that stopped short
# On a rig's owner and followers: the setting a driver reading its handles' transforms and its
# pins' keyable amounts writes (:func:`keep_handles_evaluated`); inside the extension's settings,
# where keying an object's custom properties (I) does not reach. And whether the driver made the
# object's animation data (Unbind then removes it).
HANDLES_WATCHED = "shapedeform.handles_watched"
ANIMATION_MADE = "animation_data_made"
# The keyable settings of each kind of pin (a rig's poses depend on them).
PIN_SETTINGS = {"OVERLAP": ("in_front", "extent"), "STARCH": ("stiffness", "extent")}
# Kept by older versions, which wrote poses into the object's own data: read only to give the
# rest shape back (``restore_legacy`` of each source), dropped on unbind.
LEGACY_GP_LAYERS, LEGACY_GP_FRAMES = "gp_layers", "gp_frames"
LEGACY_KEYS = (LEGACY_GP_LAYERS, LEGACY_GP_FRAMES, "baked_gp_frames", "own_graph")


# -- the graph and the plane ------------------------------------------------------------------

def store_graph(settings, plane, graph):
    """Keep ``plane`` (Plane) and ``graph`` (solver.Graph) on an owner's ``settings``."""
    settings["plane"] = plane.to_array()
    settings["graph_points"] = graph.points.ravel()
    settings["graph_edges"] = graph.edges.astype(np.int32).ravel()
    settings["graph_loops"] = np.concatenate(graph.boundary_loops).astype(np.int32)
    settings["graph_loop_sizes"] = np.array([len(loop) for loop in graph.boundary_loops], dtype=np.int32)
    settings["graph_triangles"] = graph.triangles.astype(np.int32).ravel()
    settings["graph_spacing"] = float(graph.spacing)  # the energy's density normalisation reads it


def read_graph(obj):
    """The stored (Plane, solver.Graph) of a bound owner; RigError when damaged."""
    settings = obj.shapedeform
    try:
        plane = Plane.from_array(settings["plane"])
        n = len(settings["graph_points"]) // 2
        points = np.asarray(settings["graph_points"], dtype=np.float64).reshape(n, 2)
        loops = np.split(np.asarray(settings["graph_loops"], dtype=np.int64),
                         np.cumsum(np.asarray(settings["graph_loop_sizes"]))[:-1])
        graph = solver.Graph(points, np.asarray(settings["graph_edges"]).reshape(-1, 2),
                             loops, np.asarray(settings["graph_triangles"]).reshape(-1, 3),
                             settings.get("graph_spacing"))  # rigs saved before it: estimated
    except (KeyError, ValueError) as err:
        raise RigError(f"'{obj.name}' has damaged rig data ({err}); unbind and bind it again") from None
    return plane, graph


def clear(settings):
    """Drop everything this module keeps on an owner's ``settings`` as ID properties (unbind)."""
    kept = (BAKED, RIGGED_KEY, RIGGED_NAMES, RIGGED_COUNT, RIGGED_ALL, LAYER_ISLANDS, CUTOUT_KEY, CUTOUT_ATTRIBUTES)
    for key in GRAPH_KEYS + kept + LEGACY_KEYS:
        settings.pop(key, None)


def quad_cutouts(quad):
    """The names of the cut-outs an image plane's rest quad is kept for (list of str).

    Names, not pointers: a pointer would be a user of the cut-out, which Blender then will not
    apply a transform to. Older versions kept one name, a string: a list of one here.
    """
    stamp = quad.get(QUAD_STAMP)
    if stamp is None:
        return []
    return [stamp] if isinstance(stamp, str) else [str(name) for name in stamp]


def stamp_quad(quad, names):
    """Keep ``names`` (the cut-outs' names) as those ``quad`` is kept for; the stamp goes when
    there are none. Written only when it changes; a library's quad is left as its file has it."""
    names = list(dict.fromkeys(names))
    if quad.library is not None or names == quad_cutouts(quad):
        return
    if names:
        quad[QUAD_STAMP] = names
    else:
        quad.pop(QUAD_STAMP, None)


def forget(obj):
    """Make ``obj`` unbound: its settings as an object never bound has them but for the
    handles' (the caller removes those)."""
    settings = obj.shapedeform
    clear(settings)
    settings.is_bound = False
    settings.kind = ""
    settings.status = ""
    settings.cage = None
    settings.original_data = None  # an image plane's quad, when it was converted to another type


# -- handles ----------------------------------------------------------------------------------

def present(handle, home=None):
    """A handle Empty that still exists in a collection.

    Deleting an object in the viewport only unlinks it: the handle's pointer keeps it alive
    as an orphan, so "deleted by hand" means "in no collection" (a character's collection
    shown only by a Collection Instance is in no scene, and its handles are there all the same).
    ``home``, the collection its rig keeps its handles in, is looked in first:
    ``Object.users_collection`` looks through every collection of the file (0.2 ms per handle
    with 5,000 objects), and a handle is looked for on every move of any of them.
    """
    if handle is None:
        return False
    if home is not None and home.objects.get(handle.name) == handle:
        return True
    return len(handle.users_collection) > 0


def present_items(obj):
    """The items of ``obj``'s handle list whose handle or pin is :func:`present`, in order."""
    settings = obj.shapedeform
    home = settings.handle_collection
    return [item for item in settings.handles if present(item.object, home)]


def handle_items(obj):
    """The owner's live position handles: [(Empty, indices (k,) int64, offsets (k, 2) float64)]."""
    found = []
    for item in present_items(obj):
        if HANDLE_INDICES in item and item.object.shapedeform.pin_kind == "POSITION":
            found.append((item.object, np.asarray(item[HANDLE_INDICES], dtype=np.int64),
                          np.asarray(item[HANDLE_OFFSETS], dtype=np.float64).reshape(-1, 2)))
    return found


def pin_items(obj, kind):
    """The owner's live pins of ``kind`` ('OVERLAP', 'STARCH'): [(Empty, graph point it is bound to)]."""
    return [(item.object, int(item[PIN_POINT])) for item in present_items(obj)
            if PIN_POINT in item and item.object.shapedeform.pin_kind == kind]


def keep_handles_evaluated(obj):
    """Have Blender evaluate the handles and pins of ``obj``'s rig (``obj`` its owner or a
    follower) wherever ``obj`` is evaluated: their transforms and the pins' keyable amounts;
    remove the driver that does it from an object that is neither (unbound, or given another
    object's animation data). True when something changed.

    A driver on the object reads each handle's transform and each pin's amounts, which makes
    them the object's dependencies: Blender then evaluates their animation with the object's,
    even where their collection is hidden, disabled in viewports or renders, or excluded (a pin's
    keyed In Front stayed at its last value there: a pose 0.6 off). Its value is never read,
    and the object's geometry does not depend on it, so a handle's move evaluates the object
    once, after the rig wrote the new pose (the modifier's Handles input, which did this before,
    evaluated it before that as well: 45 ms per move of a 200,000-vertex plane against 26).
    The driver is made again where it no longer fits (a handle deleted, the animation data
    replaced, the extension disabled and enabled, which marks it invalid). A library's rig
    keeps what its file made.
    """
    if obj.library is not None or obj.override_library is not None:
        return False
    owner = obj if is_owner(obj) else owner_of(obj) if is_follower(obj) else None
    wanted = _watched_targets(owner) if owner is not None else []
    fcurve = _watching_driver(obj)
    animation = obj.animation_data
    if fcurve is not None:
        if fcurve.driver.is_valid and wanted == [(v.targets[0].id, v.type, v.targets[0].data_path)
                                                 for v in fcurve.driver.variables]:
            return False
        animation.drivers.remove(fcurve)
    elif not wanted:
        return False
    if not wanted:
        if obj.shapedeform.pop(ANIMATION_MADE, False) and animation.action is None and not animation.drivers \
                and not animation.nla_tracks:
            obj.animation_data_clear()
        return True
    if animation is None:
        obj.shapedeform[ANIMATION_MADE] = True
    driver = obj.driver_add(HANDLES_WATCHED).driver
    driver.type = "SUM"
    for i, (handle, kind, data_path) in enumerate(wanted):
        variable = driver.variables.new()
        variable.name, variable.type = f"handle_{i}", kind
        target = variable.targets[0]
        target.id = handle
        if kind == "TRANSFORMS":
            target.transform_type, target.transform_space = "LOC_X", "WORLD_SPACE"
        else:
            target.data_path = data_path
    return True


def _watched_targets(owner):
    """What the driver of :func:`keep_handles_evaluated` reads, as (Empty, variable type, data
    path): each handle's transform, each pin's keyable amounts."""
    wanted = []
    for item in present_items(owner):
        handle = item.object
        if handle.shapedeform.pin_kind == "POSITION":
            wanted.append((handle, "TRANSFORMS", ""))
        else:
            wanted.extend((handle, "SINGLE_PROP", f"shapedeform.{name}")
                          for name in PIN_SETTINGS[handle.shapedeform.pin_kind])
    return wanted


def _watching_driver(obj):
    """The driver F-Curve of :func:`keep_handles_evaluated` on ``obj``, or None."""
    return obj.animation_data.drivers.find(HANDLES_WATCHED) if obj.animation_data is not None else None


def watches_handles(obj):
    """Whether ``obj`` has the driver :func:`keep_handles_evaluated` makes."""
    return _watching_driver(obj) is not None


# -- the cage and the modifier ----------------------------------------------------------------

def make_cage(obj, plane, graph, collection, islands=None):
    """The cage object of ``obj``'s rig, at rest, parented to it and linked into ``collection``;
    ``islands`` (each graph point's island number) where ``obj``'s points carry theirs."""
    rest = plane.to_3d(graph.points).astype(np.float32)
    mesh = bpy.data.meshes.new(f"{obj.name} Cage")
    mesh.from_pydata(rest.tolist(), [], graph.triangles.tolist())
    mesh.attributes.new(nodes.REST, "FLOAT_VECTOR", "POINT").data.foreach_set("vector", rest.ravel())
    if islands is not None:
        mesh.attributes.new(nodes.ISLAND, "INT", "POINT").data.foreach_set("value", islands)
    mesh.update()
    cage = bpy.data.objects.new(f"{obj.name} Cage", mesh)
    collection.objects.link(cage)
    if obj.type == "CURVE" and obj.data.use_path:
        # A child of a curve with path animation rides the path, so it depends on the curve's
        # geometry, which depends on the cage: a cycle. The cage copies the curve's transform
        # instead (Apply Transform then is not followed; the README says so).
        cage.constraints.new("COPY_TRANSFORMS").target = obj
    else:
        cage.parent = obj
        cage.matrix_parent_inverse.identity()
    cage.display_type = "WIRE"
    cage.hide_render = True
    cage.hide_select = True
    cage.hide_viewport = True
    cage.shapedeform.rig = obj
    return cage


def turn_path_off(curve):
    """Turn the Path Animation of ``curve`` (curve data) off for a rig, marking that Bind did."""
    curve.use_path = False
    curve[PATH_TURNED_OFF] = True


def turn_path_back_on(curve):
    """Turn the Path Animation of ``curve`` (curve data) on again where :func:`turn_path_off`
    turned it off, and drop the mark."""
    if curve.pop(PATH_TURNED_OFF, False):
        curve.use_path = True


def lock_interface(scene):
    """Turn Render > Lock Interface on in ``scene``, whose frame handlers pose rigs while a
    render reads the scene from another thread (saved in the file, so farm and F12 renders are
    safe), marking that it did (:data:`INTERFACE_LOCKED` True); a lock the user turned on is left
    theirs, and marked so (False). True when it turned the lock on."""
    if scene.render.use_lock_interface:
        if INTERFACE_LOCKED not in scene:
            scene[INTERFACE_LOCKED] = False
        return False
    scene.render.use_lock_interface = True
    scene[INTERFACE_LOCKED] = True
    return True


def lock_scenes_showing_rigs():
    """:func:`lock_interface` in each local scene that shows a rig (:func:`owners`) and bears no
    mark: a shot that links a character with an override, appends it, or shows it by a
    Collection Instance binds nothing itself (QA: its F12 renders ran unlocked). A marked scene
    was seen before: a lock turned off since stays off; one that shows no rig any more is
    unlocked (:func:`unlock_interface`). Returns the scenes it turned the lock on in."""
    local = [scene for scene in bpy.data.scenes if scene.library is None]
    for scene in local:
        if INTERFACE_LOCKED in scene:
            unlock_interface(scene)
    if not bound_objects():
        return []
    return [scene for scene in local if INTERFACE_LOCKED not in scene and owners(scene) and lock_interface(scene)]


def unlock_interface(scene):
    """Turn ``scene``'s Lock Interface off again where :func:`lock_interface` turned it on and
    the scene shows no rig any more (:func:`owners`), and drop the mark."""
    if scene.library is None and INTERFACE_LOCKED in scene and not owners(scene):
        if scene[INTERFACE_LOCKED]:
            scene.render.use_lock_interface = False
        del scene[INTERFACE_LOCKED]


def follows_by_constraint(obj):
    """Whether the rig of ``obj`` (its owner, or a follower's own cage) follows it by
    constraints (a curve bound with Path Animation on) rather than as its children: its cage
    tells, as it was made at Bind."""
    cage = obj.shapedeform.cage
    return cage is not None and cage.parent != obj


def path_carries_rig(obj):
    """Whether the Path Animation of curve ``obj``, turned on after Bind, carries its rig's
    handles and cage (the curve's children) along the path."""
    return obj.type == "CURVE" and obj.data.use_path and not follows_by_constraint(obj)


def own_mesh(cage):
    """The cage's mesh, made the file's own first when it is a library's; None when the cage
    itself is library data (nothing here can change it).

    A library override of a rigged character has the library's cage mesh, which nothing here
    can change (a pose or bake written there is lost on saving, and shows in every other
    override of the character meanwhile). The cage takes a local copy, its own from now on, and
    so do the cages of duplicates following the rig, which share its mesh.
    """
    if cage.library is not None:
        return None
    mesh = cage.data
    if mesh.library is not None:
        shared, mesh = mesh, mesh.copy()
        for other in bpy.data.objects:
            if other.data == shared and other.shapedeform.rig == cage.shapedeform.rig and other.library is None:
                other.data = mesh
    return mesh


def bake_action_name(cage):
    """The name of the action the bake of ``cage`` keys its shape keys in (Blender numbers it
    where the name is taken)."""
    return f"{cage.name} Shape Deform Bake"


def copy_cage_mesh(mesh, cage):
    """A copy of the cage mesh ``mesh`` for ``cage``, the cage object of a rig of its own, with a
    bake of its own.

    Copying a mesh copies its shape keys, not the actions that key them: the two rigs' bakes
    would be one action, and retiming one's keys would retime the other's. Each bake action
    (marked :data:`BAKE_MARK`) the copy's Key plays, active or in the NLA, is replaced by a copy,
    in the same slot, marked as well (so Clear Bake removes it with its Key) and named after
    ``cage`` as its own bake's would be (:func:`bake_action_name`); other actions stay shared,
    as Blender's own copies leave them.
    """
    copy = mesh.copy()
    key = copy.shape_keys
    copies = {}  # one copy of an action however many strips play it
    for holder in compat.action_holders(key.animation_data if key is not None else None):
        action, slot = holder.action, holder.action_slot
        if action is None or not action.get(BAKE_MARK):
            continue
        if action not in copies:
            copies[action] = action.copy()
            copies[action].name = bake_action_name(cage)
        holder.action = copies[action]
        if slot is not None:
            holder.action_slot = copies[action].slots[slot.identifier]
    return copy


def write_pose(cage, points, settled=True):
    """Write the pose (n, 3) float32 into the cage (:func:`own_mesh`); False when a bake holds
    it (shape keys) or the cage is library data. ``settled`` False marks it as a solve that
    stopped short of what a render gives, kept with the pose so that an undo step holding it
    brings the mark back (:func:`is_unsettled`)."""
    mesh = own_mesh(cage)
    if mesh is None or mesh.shape_keys is not None:
        return False
    if settled:
        mesh.pop(UNSETTLED, None)
    elif not mesh.get(UNSETTLED):
        mesh[UNSETTLED] = True
    position = mesh.attributes["position"].data
    if len(points) == len(mesh.vertices) and np.array_equal(_points(mesh, position), points):
        return True  # already shown: writing would have Blender evaluate every deformed object again
    # Through the vertices, which tag the geometry alone: a write through the position
    # attribute tags everything about the mesh, which cost 20 ms more in a scene of 5,000
    # objects (docs/addon_speed.md).
    mesh.vertices.foreach_set("co", points.ravel())
    return True


def is_unsettled(owner):
    """Whether ``owner``'s cage shows a pose marked unsettled by :func:`write_pose`."""
    cage = owner.shapedeform.cage
    return cage is not None and cage.data is not None and bool(cage.data.get(UNSETTLED))


def follow_library_cage(cage):
    """On a library override whose cage has its local copy of the library's mesh: when the
    library's rig was bound again (its cage's rest differs from the copy's), point the cage back
    at the library's mesh, so the next pose copies it afresh. The owner's graph comes back from
    the library on reopening; the stale copy no longer fitted it, and nothing in the shot could
    replace it (unbind is the library's). Bound again on the same graph, the rig may number its
    islands anew (:func:`island_numbers`), as the library's meshes then do: the copy takes the
    new numbers and keeps its pose and bake."""
    reference = cage.override_library.reference if cage.override_library is not None else None
    if reference is None or reference.data is None or cage.data.library is not None:
        return
    library_mesh, copy = reference.data, cage.data
    if library_mesh == copy or nodes.REST not in library_mesh.attributes:
        return
    if not (nodes.REST in copy.attributes and len(library_mesh.vertices) == len(copy.vertices)
            and np.array_equal(_points(library_mesh, library_mesh.attributes[nodes.REST].data),
                               _points(copy, copy.attributes[nodes.REST].data))):
        cage.data = library_mesh
        return
    islands = islands_of(library_mesh)
    if islands is not None and not np.array_equal(islands, islands_of(copy)):
        if nodes.ISLAND not in copy.attributes:
            copy.attributes.new(nodes.ISLAND, "INT", "POINT")
        copy.attributes[nodes.ISLAND].data.foreach_set("value", islands)
        copy.update()


def _points(mesh, data, name="vector"):
    """Points (n, 3) float32 of ``mesh`` from ``data`` (an attribute's or a shape key's)."""
    flat = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    data.foreach_get(name, flat)
    return flat.reshape(-1, 3)


def shown_pose(cage):
    """The pose the cage shows, (n, 3) float64 in rig space: its positions, or where a bake
    holds it the mix of its shape keys at their current values (relative keys) or time
    (absolute keys, linear, as a bake makes them)."""
    key = cage.data.shape_keys
    if key is None:
        return _points(cage.data, cage.data.attributes["position"].data).astype(np.float64)
    if not key.use_relative:
        return _pose_in_time(cage.data, key)
    mix = _points(cage.data, key.reference_key.data, "co").astype(np.float64)
    for block in key.key_blocks:
        if block != key.reference_key and block.value and not block.mute:
            mix += block.value * (_points(cage.data, block.data, "co").astype(np.float64)
                                  - _points(cage.data, block.relative_key.data, "co"))
    return mix


def _pose_in_time(mesh, key):
    """What absolute shape keys with linear interpolation show at the Key's Evaluation Time, as
    Blender works it out (in float32, on the keys' places, a hundredth of their times): the key
    at that time, or the blend of the two around it; the first or last key outside them."""
    blocks = key.key_blocks
    if key.get(BAKE_IN_TIME):  # a bake's: its keys' times are known exactly
        times = np.concatenate([[0.0], bake_key_times(len(blocks) - 1)]).astype(np.float32)
    else:
        times = np.empty(len(blocks), dtype=np.float32)
        blocks.foreach_get("frame", times)
    places = times / np.float32(100.0)
    place = min(max(np.float32(key.eval_time) / np.float32(100.0), places[0]), places[-1])
    after = int(np.searchsorted(places, place))  # the first key at or after it
    shown = _points(mesh, blocks[after].data, "co").astype(np.float64)
    if places[after] == place or after == 0:
        return shown
    share = float((place - places[after - 1]) / (places[after] - places[after - 1]))
    return share * shown + (1.0 - share) * _points(mesh, blocks[after - 1].data, "co")


def bake_key_times(count):
    """Evaluation Times (count,) float32 of the keys of a bake of ``count`` frames, after its
    reference key at 0: 10 apart (Blender's own spacing of absolute keys), closer for a bake
    too long for the times Blender allows (over 104,856 frames), at least 0.5 apart (a key's
    place, a hundredth of its time, is then well over Blender's 0.001 from the next, and
    Blender's 2,097,149 frames fit)."""
    top = bpy.types.Key.bl_rna.properties["eval_time"].hard_max
    spacing = max(min(10.0, top / (count + 1)), 0.5)
    return (spacing * np.arange(1, count + 1)).astype(np.float32)


# A rig numbers its islands from a first number of its own (:func:`island_numbers`), so that a
# rigged puppet joined into another keeps numbers that are none of that rig's. Every number stays
# under ISLANDS_END = 2**20: subdivision (Refine, a Subdivision Surface before the rig) mixes
# integer attributes in single precision, which put points of numbers near 2**23 a number off
# (QA: a body's points flew with its arm); measured exact below 2**22 at three levels, so 2**20 leaves
# a margin of 4.
ISLANDS_PER_RIG = 4096
ISLANDS_END = 2**20


def island_numbers(pieces, data=None):
    """Each graph point's island number for a new rig of ``data`` (the owner's mesh), (n,)
    int32, from its piece (n,) (0 to k - 1): from a first number that is a multiple of
    :data:`ISLANDS_PER_RIG`, the one another rig of ``data`` numbers from (its vertices keep
    that rig's numbers, which both then read), else one drawn at random unlike those of the
    file's rigs (a rig bound by an older version numbered from 1). A rig of more islands than
    that numbers them from 1."""
    pieces = np.asarray(pieces, dtype=np.int32)
    if pieces.max(initial=0) + 1 >= ISLANDS_PER_RIG:
        return pieces + 1
    numbered = [(obj.data, first_island(obj.shapedeform.cage.data)) for obj in bound_objects() if is_owner(obj)]
    numbered = [(owned, first) for owned, first in numbered if first is not None]  # a rig of one island has none
    same_data = [first for owned, first in numbered if data is not None and owned == data]
    if same_data:
        return pieces + same_data[0] + 1
    return pieces + _free_first_island(first for _, first in numbered) + 1


def first_island(mesh):
    """The first number (a multiple of :data:`ISLANDS_PER_RIG`) a rig numbers its islands from,
    from its cage's mesh; None where it keeps none."""
    islands = islands_of(mesh)
    return None if islands is None or not len(islands) else int(islands.min()) // ISLANDS_PER_RIG * ISLANDS_PER_RIG


def _free_first_island(taken):
    """A first island number none of ``taken`` has (0 when all are), drawn at random: rigs bound
    in different files and appended into one then differ too, as rigs of one file do."""
    free = sorted(set(range(ISLANDS_PER_RIG, ISLANDS_END, ISLANDS_PER_RIG)) - set(taken))
    return random.choice(free) if free else 0


def renumber_islands(cage_mesh, meshes=()):
    """Number anew the islands of a copied rig: its cage's mesh ``cage_mesh`` and ``meshes``,
    the meshes whose vertices read only this rig (its owner's, its followers'), from a first
    number no other rig has. A rig given a copy of another's cage (Shift+D with its handles, a
    character appended twice) otherwise kept its original's numbers, which the original read as
    its own islands in a mesh the copy was joined into. A rig numbered from 1 (by an older
    version) is left as it is."""
    first = first_island(cage_mesh)
    if not first:
        return
    taken = [first_island(obj.shapedeform.cage.data) for obj in bound_objects() if is_owner(obj)]
    shift = _free_first_island(taken) - first
    for data in (cage_mesh, *meshes):
        islands = islands_of(data)
        if islands is None:
            continue
        mine = (islands >= first) & (islands < first + ISLANDS_PER_RIG)
        islands[mine] += shift
        data.attributes[nodes.ISLAND].data.foreach_set("value", islands)
        data.update_tag()


def islands_of(mesh):
    """Each point's island number, (n,) int32, that ``mesh`` keeps (:data:`nodes.ISLAND`, see
    :func:`island_numbers`: on a cage's points, or a mesh's vertices; 0 where not known), or
    None where it keeps none; for grease pencil data, each layer's."""
    attribute = mesh.attributes.get(nodes.ISLAND)
    if attribute is None or attribute.domain not in ("POINT", "LAYER") or attribute.data_type not in ("INT", "INT8"):
        return None
    islands = np.empty(len(attribute.data), dtype=np.int32)
    attribute.data.foreach_get("value", islands)
    return islands


def rest_of(cage):
    """The cage's rest points (n, 3) float32, as stored at bind time."""
    return _points(cage.data, cage.data.attributes[nodes.REST].data)


def add_modifier(obj, cage, inputs=None):
    """Give ``obj`` the deformer modifier driven by ``cage`` (at the end of its stack), its
    other inputs at the node group's defaults but for ``inputs`` ({input name: value})."""
    group = nodes.node_group()
    modifier = obj.modifiers.new(MODIFIER_NAME, "NODES")
    modifier.node_group = group
    modifier.show_in_editmode = True
    ids = nodes.input_identifiers(group)
    values = {nodes.CAGE_INPUT: cage,
              nodes.RIGGED_INPUT: obj.shapedeform.get(RIGGED_KEY, ""), **(inputs or {})}
    for name, value in values.items():
        compat.set_modifier_input(modifier, ids[name], value)
    return modifier


def modifiers_of(obj):
    """The object's deformer modifiers (normally one)."""
    return [m for m in obj.modifiers
            if m.type == "NODES" and m.node_group is not None and nodes.VERSION_KEY in m.node_group]


def point_inputs(obj, values):
    """Set the inputs ``values`` ({input name: value}) of ``obj``'s deformer modifiers where
    they differ; True when something changed (the object is then tagged for an update)."""
    changed = False
    for modifier in modifiers_of(obj):
        ids = nodes.input_identifiers(modifier.node_group)
        for name, value in values.items():
            key = ids.get(name)
            if key is not None and compat.modifier_input(modifier, key) != value:
                compat.set_modifier_input(modifier, key, value)
                changed = True
    if changed:
        obj.update_tag()
    return changed


# -- which rig ---------------------------------------------------------------------------------

def is_owner(obj):
    """``obj`` is bound and its cage is its own (not a duplicate following another's rig)."""
    settings = obj.shapedeform
    return settings.is_bound and settings.cage is not None and settings.cage.shapedeform.rig == obj.original


def is_follower(obj):
    """``obj`` is a duplicate of a rig's owner: it shows that rig's pose, it has no rig of its own."""
    settings = obj.shapedeform
    return settings.is_bound and settings.cage is not None and settings.cage.shapedeform.rig not in (None, obj.original)


def other_rigged_users(obj):
    """The other objects with ``obj``'s data that a rig deforms: owners, and followers of a rig.

    What Bind changed on the data (a mesh's islands, a curve's Path Animation, the attribute of
    a drawing's rigged layers) serves them too: the last of them to be unbound gives it back.
    Unbinding an owner releases its followers first, so they no longer count then.
    """
    data = obj.data
    return [other for other in bpy.data.objects
            if other.data == data and other != obj.original and (is_owner(other) or is_follower(other))]


def is_legacy(obj):
    """Bound by an older version of the extension, which wrote poses into the object's data."""
    settings = obj.shapedeform
    return settings.is_bound and settings.cage is None and not modifiers_of(obj)


def owner_of(obj):
    """The owner of the rig ``obj`` belongs to (itself, as handle, cage or follower), or None."""
    if obj is None:
        return None
    settings = obj.shapedeform
    if settings.rig is not None:  # a handle or a cage
        return settings.rig if settings.rig.shapedeform.is_bound else None
    if is_follower(obj):
        return settings.cage.shapedeform.rig
    return obj if settings.is_bound else None


def active_rig(context):
    """The rig the user means: :func:`owner_of` the active object (None when it has none)."""
    return owner_of(context.active_object)


def rig_space(obj):
    """World matrix (4, 4) of the owner's rig space: the cage's (the owner's at bind time).

    Read through the cage's relation to its owner: Blender may leave a hidden object's own
    world matrix stale (identity after some undo steps), though it evaluates it right.
    """
    cage = obj.shapedeform.cage
    world = np.array(obj.matrix_world, dtype=np.float64)
    if cage is None:
        return world
    if cage.parent == obj:
        return world @ _cage_in_owner(cage)
    return np.array(cage.matrix_world, dtype=np.float64)


def _cage_in_owner(cage):
    return np.array(cage.matrix_parent_inverse, dtype=np.float64) @ np.array(cage.matrix_basis, dtype=np.float64)


def rig_to_object(obj):
    """Matrix (4, 4) from the owner's rig space to its local space: identity until the user
    applies a transform (Apply Transform moves the data and leaves the cage, a child, where it
    is), then the transform the data got since binding. Read from the cage's parenting where
    it has one, so an object scaled to zero keeps it."""
    cage = obj.shapedeform.cage
    if cage is not None and cage.parent == obj:
        return _cage_in_owner(cage)
    return affine_inverse(np.array(obj.matrix_world, dtype=np.float64)) @ rig_space(obj)


def require_local(obj, action):
    """Raise RigError when ``obj``'s rig is a library's (linked, or a library override, whose
    handle list and collections the library holds): ``action`` (a phrase) is done there."""
    require_posable(obj, action)
    if obj.override_library is None:
        return
    raise RigError(f"'{obj.name}' comes from the library '{obj.override_library.reference.library.name}': "
                   f"{action} in that file (here its handles move and key, and it bakes)")


def local_refusal(obj, action):
    """:func:`require_local`'s message, or "" (for an operator's poll)."""
    try:
        require_local(obj, action)
    except RigError as err:
        return str(err)
    return ""


def require_posable(obj, action):
    """Raise RigError when ``obj`` is linked from a library without an override: nothing in
    this file can move its handles or keep what is written into its cage (Blender drops edits
    of linked data on saving), or when the file of the library it comes from is missing.
    ``action`` is a phrase: "bake it"."""
    library = missing_library(obj)
    if library is not None:
        raise RigError(f"'{obj.name}' comes from the library '{library.name}', whose file "
                       f"{bpy.path.abspath(library.filepath, library=library.library)} is missing: find it (File > "
                       "External Data > Find Missing Files, or Relocate in the Outliner's Blender File view), "
                       f"then {action}")
    if obj.library is None:
        return
    raise RigError(f"'{obj.name}' comes from the library '{obj.library.name}' without a library override: "
                   f"{action} in that file, or make a library override of it here (Object > Library "
                   "Override) to move its handles, key them and bake")


def missing_library(obj):
    """The library whose file is missing that ``obj`` (linked, or a library override) comes
    from, or None. Blender then puts placeholders in for the linked data (the override's
    reference, its modifier's node group, its cage), which pose nothing."""
    reference = obj.override_library.reference if obj.override_library is not None else obj
    if reference is None or reference.library is None or not reference.is_missing:
        return None
    return reference.library


def is_baked(obj):
    """Whether the owner ``obj`` plays a bake (the live rig then leaves it alone).

    A bake is the cage's shape keys, so they decide: a library override keeps them with its
    local cage mesh, but its owner's ID properties come back from the library on reopening
    (a Clear Bake made in the shot would otherwise leave the ``BAKED`` mark of the library's
    bake over a cage with no keys, and the rig frozen). Keys of a bake from before the Key was
    marked count where the owner has the mark."""
    cage = obj.shapedeform.cage
    keys = cage.data.shape_keys if cage is not None else None
    if keys is None:
        return False
    return bool(keys.get(BAKE_MARK)) or (BAKED in obj.shapedeform and len(keys.key_blocks) > 1)


def store_bake_source(cage, digest, numbers):
    """Keep on the bake ``cage`` plays (its Key) what it was made from (:func:`.bake_source.fingerprint`):
    its ``digest`` and ``numbers`` ((k,) float64). On the Key rather than the owner: they go
    with the bake (Clear Bake, a copy's cage), and stay in a library override's local cage mesh,
    where the owner's ID properties come back from the library on reopening."""
    key = cage.data.shape_keys
    key[BAKE_SOURCE] = digest
    key[BAKE_SOURCE_NUMBERS] = np.asarray(numbers, dtype=np.float64)


def bake_source(cage):
    """What :func:`store_bake_source` kept for the bake ``cage`` plays, (digest, (k,) float64
    ndarray); None without a bake, or for one made before both were kept (not known)."""
    key = cage.data.shape_keys if cage is not None and cage.data is not None else None
    if key is None or BAKE_SOURCE not in key or BAKE_SOURCE_NUMBERS not in key:
        return None
    return key[BAKE_SOURCE], np.asarray(key[BAKE_SOURCE_NUMBERS], dtype=np.float64)


def owners(scene, depsgraph=None, evaluated=True):
    """Rig owners that ``scene`` shows (:func:`shown_objects`: a character shown in a shot by a
    Collection Instance, in a set that is itself instanced, or in a Background Set too), and the
    owners of the duplicates following a rig it shows (a copy moved to another scene poses there
    with its rig's handles, which its modifier has Blender evaluate wherever it is). Linked rigs
    (library data without an override) are left out: nothing here can pose them (a bake in their
    own file can).

    Rigs the scene shows by other ways (a Geometry Nodes *Collection Info* node, particles
    rendering a collection) are found in ``depsgraph`` (by default the context view layer's,
    when it is ``scene``'s): those it evaluates are shown; not with ``evaluated`` False (a caller
    on a render's thread, where the context's depsgraph is not to be read).
    """
    found = []
    bound = set(bound_objects())
    for obj in shown_objects(scene):
        if obj not in bound:  # most of a big scene, every frame: a set lookup, no property read
            continue
        owner = owner_of(obj)
        if _posable_owner(owner):
            found.append(owner)
    if evaluated:
        found += _evaluated_owners(scene, depsgraph, set(found))
    return list(dict.fromkeys(found))  # shown twice, posed once


def shown_objects(scene):
    """The objects ``scene`` shows, linked ones too, in scene order: its own, its Background
    Sets', and those of the collections they instance, at any depth (an object may come twice)."""
    objects, shown, seen = list(scene.objects), {scene.session_uid}, set()
    backdrop = scene.background_set
    while backdrop is not None and backdrop.session_uid not in shown:
        shown.add(backdrop.session_uid)
        objects.extend(backdrop.objects)
        backdrop = backdrop.background_set
    for obj in objects:  # grows with the objects of each instanced collection
        collection = obj.instance_collection if obj.instance_type == "COLLECTION" else None
        if collection is not None and collection.session_uid not in seen:
            seen.add(collection.session_uid)  # an instance cycle ends here
            objects.extend(collection.all_objects)
    return objects


def _evaluated_owners(scene, depsgraph, known):
    if depsgraph is None:
        view_layer = getattr(bpy.context, "view_layer", None)
        if view_layer is None or scene.view_layers.get(view_layer.name) != view_layer:
            return []
        depsgraph = view_layer.depsgraph
        if depsgraph is None:  # not evaluated yet: a file being opened
            return []
    found = []
    for obj in bound_objects():
        if obj not in known and obj.shapedeform.is_bound and obj.evaluated_get(depsgraph).is_evaluated:
            owner = owner_of(obj)
            if owner not in known and _posable_owner(owner):
                found.append(owner)
    return found


# The bound objects of the file, owners and followers: what :func:`owners` looks through for
# rigs the scene shows by other ways than its objects, on every frame, and what handlers look
# through for rigs instead of every object. Made again when the file's number of objects changes
# (a bind makes a cage, a duplicate or an append adds objects, a delete removes them) or one of
# its objects was removed; dropped when a file is opened, an undo step restored, or an object
# bound or unbound (:func:`forget_bound`).
_bound = {"count": -1, "objects": []}


def bound_objects():
    """Every bound object of the file (owners and followers), a list kept between calls."""
    count = len(bpy.data.objects)
    if count != _bound["count"] or not all(map(_exists, _bound["objects"])):  # one removed, another added
        _bound["objects"] = [obj for obj in bpy.data.objects if obj.shapedeform.is_bound]
        _bound["count"] = count
    return _bound["objects"]


def _exists(obj):
    try:
        return obj.name is not None
    except ReferenceError:
        return False


def forget_bound():
    """Drop the list :func:`bound_objects` keeps."""
    _bound["count"], _bound["objects"] = -1, []


def _posable_owner(obj):
    return is_owner(obj) and obj.library is None


def relink_overrides():
    """Point the rig's references in library overrides back at the overrides.

    Making a library override points everything in its hierarchy at the overridden copies, and
    Blender saves that for the rig's properties only while the extension is enabled: a shot
    saved without it (a lighter's machine) comes back with its overrides' cage, handles and
    collections naming the library's objects, and the rig would follow those. Each reference
    to a linked object or collection that has an override in the same hierarchy is moved to
    that override.
    """
    overrides = {}
    for block in (*bpy.data.objects, *bpy.data.collections):
        override = block.override_library
        if block.library is None and override is not None and override.reference is not None:
            overrides[(override.reference, override.hierarchy_root)] = block
    if not overrides:
        return
    for obj in bpy.data.objects:
        settings = obj.shapedeform
        if obj.library is None and obj.override_library is not None and (settings.is_bound or settings.rig):
            _relink(settings, obj.override_library.hierarchy_root, overrides)


def _relink(group, root, overrides):
    for prop in group.bl_rna.properties:
        if prop.type == "COLLECTION" and prop.identifier != "rna_type":
            for item in getattr(group, prop.identifier):
                _relink(item, root, overrides)
        elif prop.type == "POINTER" and prop.identifier != "rna_type":
            value = getattr(group, prop.identifier)
            if isinstance(value, bpy.types.ID) and value.library is not None:
                replacement = overrides.get((value, root))
                if replacement is not None:
                    setattr(group, prop.identifier, replacement)
