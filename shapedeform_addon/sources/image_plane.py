# SPDX-License-Identifier: GPL-3.0-or-later
"""Image planes (Import Images as Planes): a textured quad whose picture has alpha.

Binding replaces the quad by a triangulated cut-out of the picture's silhouette: the paper's
graph of the traced outline, so the cut-out is its own graph. The picture is traced through the
UV map it is read by (a UV Map node's, else the render-active one); each of the quad's UV maps
goes onto the cut-out through the quad's own two triangles, each mapped affinely as Blender
interpolates a face's UVs, so every point shows the texel it showed on the quad and the picture
looks the same before posing. The quad's mesh is kept (``obj.shapedeform.original_data``) and
given back on unbind, untouched but for the materials given to the cut-out (:func:`unbind`); the
cut-out is then deleted.
"""

import hashlib
import os
from typing import NamedTuple

import bpy
import numpy as np
from mathutils import Matrix

from ...solver.outline import outline_graph
from ...solver.rigging.plane import fit_plane, transform_points
from ...solver.rigging.silhouette import image_cutout, map_by_triangles, shown_frame, specks
from ...solver.triangulate import triangle_cross
from .. import rig_format
from ..rig_format import CUTOUT_ATTRIBUTES, CUTOUT_KEY
from ..errors import RigError
from . import mesh as mesh_source
from .prepared import Prepared

# Shared with meshes once the cut-out is in place.
selected, selected_islands = mesh_source.selected, mesh_source.selected_islands


def _material_index(obj):
    """The material slot the quad's face shows (an index past the last slot shows the last)."""
    return min(obj.data.polygons[0].material_index, len(obj.material_slots) - 1)


class Picture(NamedTuple):
    """An image node and the group nodes it lies in, outermost first (empty in the material's own tree)."""
    node: bpy.types.Node
    groups: tuple


def _picture(obj):
    """The :class:`Picture` of the material the quad's face shows whose image has alpha, or
    None: the first whose alpha the material reads (:func:`_alpha_reader`: a shader's Alpha),
    else the first. An image Blender could not load (its file missing, a sequence no frame of
    which was shown yet) has no channels to tell: it counts, so Bind can say what is wrong
    rather than rig the bare quad."""
    found = _pictures(obj)
    return min(found, key=lambda picture: _alpha_reader(picture) is None) if found else None


def _pictures(obj):
    """The :class:`Picture` s with alpha of the material the quad's face shows, in its tree and in
    the node groups it uses (a group used twice gives its pictures twice)."""
    if not obj.material_slots:
        return []
    material = obj.material_slots[_material_index(obj)].material
    if material is None or material.node_tree is None:
        return []
    return [picture for picture in _image_nodes(material.node_tree, ())
            if picture.node.image is not None and picture.node.image.channels in (0, 4)
            and picture.node.image.alpha_mode != "NONE"]


def _image_nodes(tree, groups):
    """Each :class:`Picture` of node ``tree``, which lies in group nodes ``groups``, and of the
    groups it uses (a material built of node groups)."""
    for node in tree.nodes:
        if node.type == "TEX_IMAGE":
            yield Picture(node, groups)
        elif node.type == "GROUP" and node.node_tree is not None:
            yield from _image_nodes(node.node_tree, (*groups, node))


# How far past a visible texel's edge the picture is cut out, in texels, by the node's
# interpolation: the reach of its filter (Linear 0.5, the cubic B-spline 1.5; Smart renders as
# Cubic) plus the outline's simplification (half a texel) and some room.
_FILTER_MARGIN = {"Closest": 1.0, "Linear": 1.0, "Cubic": 2.5, "Smart": 2.5}


def _image(obj):
    found = _pictures(obj)  # cheap: is_image_plane is asked by operators' polls
    return found[0].node.image if found else None


def _alpha(obj, node):
    """(H, W) float32: the alpha of what ``node`` shows, rows bottom up; and advice (str).

    A still's alpha; for an image sequence the most opaque of its frames' (every frame the node
    plays is then inside the cut-out); a movie is rigged whole (its frames cannot be read here)."""
    image = node.image
    if image.source == "SEQUENCE":
        return _sequence_alpha(obj, node), ""
    width, height = image.size
    if width < 1 or height < 1:
        raise RigError(f"'{obj.name}': its image '{image.name}' has no pixels (is the file missing?)")
    if image.source == "MOVIE":
        return np.ones((height, width), np.float32), \
            f"'{image.name}' is a movie: its whole frame is rigged (a cut-out of one frame would clip the others)"
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(height, width, 4)[..., 3], ""


def _sequence_alpha(obj, node):
    """The most opaque alpha of the frames ``node`` plays (its image user's frame offset and
    duration), each read from its file; the image user's frame is put back."""
    image, user = node.image, node.image_user
    shown = user.frame_current
    alpha = None
    try:
        for frame in range(user.frame_offset + 1, user.frame_offset + max(user.frame_duration, 1) + 1):
            user.frame_current = frame
            path = bpy.path.abspath(image.filepath_from_user(image_user=user), library=image.library)
            if not os.path.isfile(path):
                continue
            still = bpy.data.images.load(path, check_existing=False)
            try:
                width, height = still.size
                pixels = np.empty(width * height * 4, dtype=np.float32)
                still.pixels.foreach_get(pixels)
            finally:
                bpy.data.images.remove(still)
            frame_alpha = pixels.reshape(height, width, 4)[..., 3]
            if alpha is not None and alpha.shape != frame_alpha.shape:
                raise RigError(f"'{obj.name}': the frames of its image sequence '{image.name}' differ in size "
                               f"({alpha.shape[1]} x {alpha.shape[0]} and {width} x {height} pixels)")
            alpha = frame_alpha if alpha is None else np.maximum(alpha, frame_alpha)
    finally:
        user.frame_current = shown
    if alpha is None or alpha.size == 0:
        raise RigError(f"'{obj.name}': no frame of its image sequence '{image.name}' was found "
                       f"(are the files missing?)")
    return alpha


def is_image_plane(obj):
    """A quad (4 vertices, one face, UVs) textured with an image that has alpha."""
    data = obj.data
    return (obj.type == "MESH" and len(data.vertices) == 4 and len(data.polygons) == 1
            and len(data.uv_layers) > 0 and _image(obj) is not None)


def _picture_uv_layer(quad, picture):
    """The UV map :class:`Picture` ``picture`` reads its picture through, and the name of a node
    on the way that changes the coordinates ("" when none).

    The map is the one a UV Map node upstream of its Vector names (through reroutes, node
    groups, in and out of the groups it lies in, and nodes such as Mapping), else the one
    Blender renders with (the render-active map, which also feeds an unwired Vector). The map
    being edited (the active one) may be a scratch map. A node that changes the coordinates (a
    Mapping node that is not the identity, a Texture Coordinate output other than UV) makes what
    is cut out differ from what renders.
    """
    # A Sphere, Tube or Box projection maps the coordinates itself (QA: not told).
    named, changed = "", picture.node.name if picture.node.projection != "FLAT" else ""
    links, groups = picture.node.inputs["Vector"].links, picture.groups
    while links:
        link = links[0]
        source = link.from_node
        if source.type == "UVMAP":
            named = source.uv_map
            break
        if source.type == "TEX_COORD":
            changed = changed or ("" if link.from_socket.name == "UV" else source.name)
            break
        if source.type == "GROUP" and source.node_tree is not None:
            inside = next((n for n in source.node_tree.nodes if n.type == "GROUP_OUTPUT" and n.is_active_output), None)
            links = inside.inputs[link.from_socket.identifier].links if inside is not None else ()
            groups = (*groups, source)
            continue
        if source.type == "GROUP_INPUT" and groups:  # out to what feeds the group node
            outer = groups[-1].inputs[link.from_socket.identifier]
            if not outer.is_linked and not _implicit(groups[-1], link.from_socket.identifier):
                changed = changed or groups[-1].name  # an unlinked input feeds its value (QA: texel 0, 0)
            links, groups = outer.links, groups[:-1]
            continue
        if source.type == "MAPPING" and not _is_identity(source):
            changed = changed or source.name
        elif source.type not in ("REROUTE", "MAPPING"):
            changed = changed or source.name
        vectors = [socket for socket in source.inputs if socket.type == "VECTOR" and socket.is_linked]
        links = vectors[0].links if vectors else ()
    layer = quad.uv_layers.get(named) or next(layer for layer in quad.uv_layers if layer.active_render)
    return layer, changed


def _implicit(group_node, identifier):
    """Whether the group input ``identifier`` of ``group_node``, unlinked, passes on the
    coordinates an unwired Vector reads (its value hidden) rather than its value."""
    socket = next((item for item in group_node.node_tree.interface.items_tree
                   if item.item_type == "SOCKET" and item.identifier == identifier), None)
    return socket is not None and socket.hide_value


def _is_identity(mapping):
    """Whether a Mapping node leaves its vectors as they are (its inputs at their rest values)."""
    rest = {"Location": (0.0, 0.0, 0.0), "Rotation": (0.0, 0.0, 0.0), "Scale": (1.0, 1.0, 1.0)}
    return all(name not in mapping.inputs or (not mapping.inputs[name].is_linked
                                              and np.allclose(mapping.inputs[name].default_value, value))
               for name, value in rest.items())


def _loop_uvs(layer):
    """(loops, 2) float64: a UV map's UV at each loop."""
    uv = np.empty(len(layer.data) * 2, dtype=np.float32)
    layer.data.foreach_get("uv", uv)
    return uv.reshape(-1, 2).astype(np.float64)




def prepare(obj, settings):
    """Read the object's rest shape and build its graph, changing nothing (see :mod:`.sources`)."""
    quad = obj.data
    picture = _picture(obj)
    node = picture.node
    corners = mesh_source.positions(quad).astype(np.float64)
    loop_vertices = np.empty(len(quad.loops), dtype=np.int32)
    quad.loops.foreach_get("vertex_index", loop_vertices)
    picture_layer, changed = _picture_uv_layer(quad, picture)
    uv = _loop_uvs(picture_layer)
    # A tiled (UDIM) picture shows another picture on each tile, of which only 1001's pixels can
    # be read (QA: another tile's plane was cut to 1001's alpha).
    other_tile = node.image.source == "TILED" and bool(np.any(np.floor(uv.mean(axis=0)) != 0.0))
    if node.extension in {"REPEAT", "MIRROR"} and node.image.source != "TILED":  # a whole tile over shows it again
        tile = np.floor(uv.mean(axis=0))  # the one holding most of the plane: UVs a hair past it stay
        mirrored = (node.extension == "MIRROR") & (tile % 2 == 1)  # odd tiles show it mirrored
        uv = np.where(mirrored, tile + 1.0 - uv, uv - tile)
    try:
        plane = fit_plane(corners)
    except ValueError as err:
        raise RigError(f"'{obj.name}' cannot be rigged: {err}") from None
    loop_points = plane.to_2d(corners[loop_vertices])
    # UVs are interpolated over the triangles Blender splits the face into, each affinely: map
    # through the same triangles, so a quad that is no parallelogram shows the same texels.
    loop_triangles = _loop_triangles(quad)
    reader = _alpha_reader(picture)
    shown = None  # what the plane shows of its picture, which the cut-out covers within
    if reader is None:
        # Nothing reads the alpha: the plane renders whole, so is it rigged (its pixels unread:
        # a 4,096-pixel square took 2.3 s to read and trace into its own frame).
        rings = [loop_points]
        notes = [f"nothing reads the alpha of its picture '{node.image.name}', so the whole plane is rigged, as "
                 "it renders (wire the picture's Alpha to the shader's to cut the plane to the picture)"]
    elif other_tile:
        rings = [loop_points]
        notes = [f"'{node.image.name}' is a tiled (UDIM) picture shown on a tile other than 1001, whose pixels "
                 "cannot be read: the whole plane is rigged"]
    else:
        rings, shown, notes = _cutout_rings(obj, node, reader, picture_layer, uv, loop_points, loop_triangles)
        notes.extend(_reading_notes(obj, picture, changed, picture_layer))
        # Clip and Extend show the picture once, however far the UVs reach (QA: a false warning).
        if node.extension in {"REPEAT", "MIRROR"} and not np.all((uv >= -1e-4) & (uv <= 1.0 + 1e-4)):
            notes.append("its UVs show the picture more than once: only the copy in the UV square is cut out")
    try:
        graph = outline_graph(rings, settings.density, cover_within=shown)
    except ValueError as err:
        raise RigError(f"'{obj.name}' cannot be rigged: {err}") from None
    vertices = plane.to_3d(graph.points).astype(np.float32)  # float32 as Blender stores them
    # Faces the way the quad does (QA: a plane mirrored and applied faces away from the plane's
    # normal, and its cut-out turned to it vanished under backface culling).
    quad_turns = triangle_cross(loop_points, loop_triangles).sum() > 0.0
    triangles = graph.triangles if quad_turns == (triangle_cross(graph.points, graph.triangles).sum() > 0.0) \
        else graph.triangles[:, ::-1]
    # Every UV map (a second one a shader reads, a scratch one) goes onto the cut-out, so each
    # still shows what it showed on the quad.
    uv_maps = [(layer.name, map_by_triangles(loop_points, _loop_uvs(layer), loop_triangles,
                                             graph.points)[triangles].astype(np.float32))
               for layer in quad.uv_layers]
    active_uv = quad.uv_layers.active_index
    material_index = _material_index(obj)
    render_uv = next(i for i, layer in enumerate(quad.uv_layers) if layer.active_render)

    def commit(o):
        cutout = _new_cutout(quad, vertices, triangles, uv_maps, active_uv, render_uv, material_index)
        # Added to the cut-outs the quad is kept for, which other planes bound on it (linked
        # duplicates bound one by one) keep: a copy's cut-out has another name, and needs a quad
        # of its own (own_quad).
        rig_format.stamp_quad(quad, [*_cutouts_in_use(quad, but=o), cutout.name])
        o.shapedeform.original_data = quad
        # To tell, at unbind, whether it was edited.
        o.shapedeform[CUTOUT_KEY] = vertices.astype(np.float32).ravel()
        o.shapedeform[CUTOUT_ATTRIBUTES] = _attribute_digests(cutout)
        o.data = cutout

    if quad.shape_keys is not None and len(quad.shape_keys.key_blocks) > 1:
        notes.append("its shape keys stop showing while it is bound (the cut-out has none; Unbind gives the quad "
                     "back with them)")
    return Prepared(plane, graph, commit, advice="; ".join(filter(None, notes)))


def _cutout_rings(obj, node, reader, picture_layer, uv, loop_points, loop_triangles):
    """The rings (in the plane) of what the picture's alpha shows of ``node``'s picture through
    the quad's UVs (``uv`` at its loops ``loop_points``, (4, 2) each), the rings of the part of
    the picture the quad shows, and what Bind says about them ([str]); ``reader`` is
    :func:`_alpha_reader`'s answer."""
    alpha, advice = _alpha(obj, node)
    alpha = np.nan_to_num(alpha, nan=0.0, posinf=1.0, neginf=0.0)  # QA: a float picture's NaN stopped Bind
    height, width = alpha.shape
    if width * height < 2:
        raise RigError(f"'{obj.name}': its image '{node.image.name}' is a single pixel: too small to cut a shape from")
    window = uv * (width, height)
    notes = [advice, *_cutout_notes(node, reader, alpha, window)]

    def to_plane(rings):  # rings in pixels
        return [map_by_triangles(uv, loop_points, loop_triangles, ring / (width, height)) for ring in rings]

    try:
        to_plane([window])  # refuses a picture map that covers no area
    except ValueError:
        raise RigError(f"'{obj.name}': its UV map '{picture_layer.name}', which shows its picture, shows none of "
                       "it (its corners' UVs lie on one line): unwrap the plane again") from None
    # Only what the plane shows: its UVs may frame part of the picture (a sprite sheet's).
    margin = _FILTER_MARGIN.get(node.interpolation, max(_FILTER_MARGIN.values()))
    try:
        # Repeating, a filtered edge blends in the opposite one (Closest filters nothing in).
        wrap = node.extension == "REPEAT" and node.interpolation != "Closest"
        rings = image_cutout(alpha, margin=margin, window=window, wrap=wrap)
    except ValueError as err:
        raise RigError(f"'{obj.name}' cannot be rigged: {err}") from None
    return to_plane(rings), to_plane(shown_frame(width, height, window)), notes


def _loop_triangles(quad):
    """The loops (t, 3) int32 of the triangles Blender splits ``quad``'s faces into."""
    quad.calc_loop_triangles()
    loops = np.empty(len(quad.loop_triangles) * 3, dtype=np.int32)
    quad.loop_triangles.foreach_get("loops", loops)
    return loops.reshape(-1, 3)


def _new_cutout(quad, vertices, triangles, uv_maps, active_uv, render_uv, material_index):
    """The cut-out mesh of ``quad``: ``vertices`` (n, 3) and ``triangles`` (t, 3), each UV map
    of ``uv_maps`` ([(name, (t, 3, 2) UVs per corner)]), the same active and render maps, and
    the quad's materials, every face showing ``material_index``."""
    cutout = bpy.data.meshes.new(f"{quad.name} Cut-out")
    cutout.from_pydata(vertices.tolist(), [], triangles.tolist())
    for name, uvs in uv_maps:
        cutout.uv_layers.new(name=name).data.foreach_set("uv", uvs.ravel())
    cutout.uv_layers.active_index = active_uv
    cutout.uv_layers[render_uv].active_render = True
    for material in quad.materials:
        cutout.materials.append(material)
    cutout.polygons.foreach_set("material_index", np.full(len(cutout.polygons), material_index, np.int32))
    cutout.update()
    return cutout


def _cutout_notes(node, reader, alpha, window):
    """What Bind says about cutting ``node``'s picture to its ``alpha`` (H, W) ([str]);
    ``window`` (k, 2) is the part of the picture the plane shows, in pixels. A node ``reader``
    (its name) on the way to the shader (an Invert, a Math node) may show other pixels than the
    alpha says; specks the cut-out leaves out are told."""
    notes = [f"'{reader}' changes its picture's alpha on the way to the shader: what is cut out may not be "
             "what renders"] if reader else []
    count, strongest = specks(alpha, window=window)
    if count:
        notes.append(f"{count} {'speck' if count == 1 else 'specks'} of its picture with less ink than one "
                     f"opaque pixel (the most opaque {strongest:.0%}) {'is' if count == 1 else 'are'} left out "
                     "of the cut-out")
    return notes


def _alpha_reader(picture):
    """How the material reads :class:`Picture` ``picture``'s alpha: "" straight into a shader's
    Alpha (through reroutes and out of the groups it lies in; or a Mix Shader's factor over a
    Transparent BSDF), None when nothing that reaches the material's output reads it (the
    node or a group it lies in muted, its Alpha unwired or muted, or into a shader left out),
    else the name of a node on the way that may change it."""
    node, groups = picture
    if node.mute or any(group.mute for group in groups):
        return None  # QA: a muted picture renders the whole quad
    reaching = {}
    changed = None
    todo = [(link, groups) for link in node.outputs["Alpha"].links]
    while todo:
        link, within = todo.pop(0)
        to, socket = link.to_node, link.to_socket
        if link.is_muted:
            continue
        if to.type == "REROUTE":
            todo.extend((onward, within) for onward in to.outputs[0].links)
            continue
        if to.type == "GROUP_OUTPUT" and within:  # out of the group node it lies in
            if to.is_active_output:
                todo.extend((onward, within[:-1]) for onward in within[-1].outputs[socket.identifier].links)
            continue
        if not all(_reaches_output(chained, reaching) for chained in (*within, to)):
            continue  # nothing renders what it reads (QA: a shader left out inside a group)
        if socket.name == "Alpha" and any(output.type == "SHADER" for output in to.outputs):
            return ""
        first = to.inputs[1].links if to.type == "MIX_SHADER" and socket == to.inputs[0] else ()
        if first and first[0].from_node.type == "BSDF_TRANSPARENT":
            return ""
        changed = changed or to.name
    return changed


def _reaches_output(node, reaching):
    """Whether ``node``'s outputs reach its tree's output (a material's active Material Output's
    Surface, a group's active Group Output), through unmuted links; ``reaching`` keeps each
    tree's answer."""
    tree = node.id_data
    if tree not in reaching:
        output = next((n for n in tree.nodes if n.type in {"OUTPUT_MATERIAL", "GROUP_OUTPUT"} and n.is_active_output),
                      None)
        sockets = ([output.inputs["Surface"]] if output.type == "OUTPUT_MATERIAL" else list(output.inputs)) \
            if output is not None else []
        found, todo = set(), [link for socket in sockets for link in socket.links]
        while todo:
            link = todo.pop()
            if not link.is_muted and link.from_node not in found:
                found.add(link.from_node)
                todo.extend(upstream for socket in link.from_node.inputs for upstream in socket.links)
        reaching[tree] = found
    return node in reaching[tree]


def _reading_notes(obj, picture, changed, picture_layer):
    """What Bind says when what it cuts out may differ from what renders: a node ``changed``
    (its name) changes the picture's coordinates, other pictures with alpha are read, or the
    same picture is read through another UV map than ``picture_layer`` or changed coordinates."""
    notes = [f"'{changed}' changes the coordinates its picture is read through: what is cut out may not be "
             "what renders"] if changed else []
    image = picture.node.image
    others, elsewhere = [], []
    for other in _pictures(obj):
        if other == picture or _alpha_reader(other) is None:
            continue
        if other.node.image != image:
            others.append(other.node.image.name)
            continue
        # The same picture again (Blender 5's importer adds a node to a material it reuses) is
        # cut out alike where it is read alike (QA: a copy through another UV map was lost).
        layer, other_changed = _picture_uv_layer(obj.data, other)
        if layer != picture_layer or other_changed:
            elsewhere.append(other.node.name)
    if others:
        notes.append(f"only the picture '{image.name}' is cut out, not " + ", ".join(map(repr, dict.fromkeys(others))))
    if elsewhere:
        notes.append(f"its picture is also read through other coordinates by {', '.join(map(repr, elsewhere))}: "
                     f"only what '{picture.node.name}' shows through UV map '{picture_layer.name}' is cut out")
    return notes


def own_quad(obj):
    """Give a duplicate of a bound image plane a quad of its own where its cut-out is its own;
    True when it did.

    Shift+D copies the cut-out but not the quad, which only the rig's settings point at: the
    copy then shared its rest quad with the plane it was copied from (the rig's owner or a
    follower of it), and an edit of either's quad after Unbind changed the other's. The quad
    names the cut-outs it is kept for (``rig_format.quad_cutouts``: each plane bound on it adds
    its own), which a copy's cut-out is not; a linked duplicate (Alt+D) shares the cut-out, so
    it shares the quad too. A cut-out the quad does not name is taken as the quad's where every
    plane bound on that quad shows it (a cut-out renamed, one bound by a version that did not
    name it, a copy whose original is gone); where another plane shows another cut-out, the
    planes showing this one get a copy of the quad, with the materials of the cut-out's slots
    where it has as many as the quad (Shift+D gives a copy copies of them with Preferences >
    Editing > Duplicate Data > Material, as it gives any plane), so Unbind gives them back.

    Parameters
    ----------
    obj : bpy.types.Object
        A follower, or a duplicate just given a rig of its own.
    """
    quad = obj.shapedeform.original_data
    if quad is None or obj.data.name in _cutouts_in_use(quad, but=obj):
        return False
    bound_on_quad = _planes_on(quad)
    sharing = [plane for plane in bound_on_quad if plane.data == obj.data]  # itself and its linked duplicates
    if len(sharing) == len(bound_on_quad):
        rig_format.stamp_quad(quad, [obj.data.name])
        return False
    own = quad.copy()
    _take_materials(own, obj.data)
    rig_format.stamp_quad(own, [obj.data.name])
    for plane in sharing:
        plane.shapedeform.original_data = own
    return True


def _planes_on(quad, but=None):
    """The objects bound on ``quad`` (keeping it to give back), but ``but``."""
    return [obj for obj in bpy.data.objects if obj != but and obj.shapedeform.original_data == quad]


def _cutouts_in_use(quad, but):
    """The names of the cut-outs ``quad`` is kept for that a plane bound on it, but ``but``,
    still shows: a name none shows (its planes unbound, or it was renamed) goes."""
    shown = {plane.data.name for plane in _planes_on(quad, but) if plane.data is not None}
    return [name for name in rig_format.quad_cutouts(quad) if name in shown]


def unbind(obj):
    """Give the quad back, with any transform applied to the cut-out since binding (Apply
    Rotation & Scale) applied to it too, so the picture stays where it is; unless the rig's
    modifier was applied or the object converted, which made the pose its own; and with the
    materials given to the cut-out, where no other plane shows the quad with others. Call while
    the rig's cage exists."""
    original = obj.shapedeform.original_data
    if original is None:
        return []
    if obj.type != "MESH" or not rig_format.modifiers_of(obj):
        # Converted, or its modifier applied: the pose is the object's own now, kept as a
        # mesh's would be (the status bar said so); the quad is not given back over it.
        obj.shapedeform.pop(CUTOUT_KEY, None)
        obj.shapedeform.pop(CUTOUT_ATTRIBUTES, None)
        rig_format.stamp_quad(original, _cutouts_in_use(original, but=obj))
        obj.shapedeform.original_data = None
        if original.users == 0:  # not given back, and no other plane shows or keeps it
            bpy.data.meshes.remove(original)
        return []
    applied = rig_format.rig_to_object(obj)
    cutout = obj.data
    as_bound = _as_bound(obj, cutout, applied)
    lost = [] if as_bound else \
        ["the edits of its cut-out's vertices, in Edit Mode or by Join or Separate (the picture's quad is "
         "back; Undo brings them back)"]
    lost += _attribute_edits(obj, cutout, uvs_too=as_bound)
    if cutout.shape_keys is not None:
        lost.append("the shape keys of its cut-out (the picture's quad has none; Undo brings them back)")
    if list(cutout.materials) != list(original.materials):
        lost += _give_materials_back(obj, cutout, original)
    obj.shapedeform.pop(CUTOUT_KEY, None)
    obj.shapedeform.pop(CUTOUT_ATTRIBUTES, None)
    # Its cut-out's name stays while another plane bound on the quad shows it (an Alt+D copy).
    rig_format.stamp_quad(original, _cutouts_in_use(original, but=obj))
    obj.data = original
    obj.shapedeform.original_data = None
    if not np.allclose(applied, np.eye(4), rtol=0.0, atol=1e-6):
        if original.users > 1:  # another object shows this quad: apply to a copy
            obj.data = original.copy()
        obj.data.transform(Matrix(applied.tolist()))
        obj.data.update()
    if cutout.users == 0:
        bpy.data.meshes.remove(cutout)
    return lost


def _take_materials(quad, cutout):
    """Put the materials of ``cutout``'s slots in ``quad``'s, where it has as many."""
    if len(quad.materials) == len(cutout.materials):
        for slot, material in enumerate(cutout.materials):
            quad.materials[slot] = material


def _give_materials_back(obj, cutout, quad):
    """Carry the materials given to ``obj``'s cut-out while bound (made single-user, or another
    chosen) onto its quad, as the quad is given back; what Unbind drops instead, as phrases.

    They stay the cut-out's alone where the quad has another number of slots (the face shows
    one by its index), or where another object shows the quad, or a cut-out of it, with other
    materials: it would change what that object shows.
    """
    if len(quad.materials) != len(cutout.materials):
        return ["the materials given to its cut-out (slots added or removed there: the picture's quad keeps its "
                "own; Undo brings them back)"]
    others = [other.name for other in bpy.data.objects
              if other != obj and (other.data == quad or other.shapedeform.original_data == quad)
              and list(other.data.materials) != list(cutout.materials)]
    if others:
        return [f"the materials given to its cut-out (the picture's quad keeps its own, which '{others[0]}' shows "
                "too; Undo brings them back)"]
    _take_materials(quad, cutout)
    return []


def _as_bound(obj, cutout, applied):
    """Whether the cut-out still has the vertices bind made (moved only by an applied transform)."""
    if CUTOUT_KEY not in obj.shapedeform or obj.shapedeform.cage is None:
        return True  # bound by a version that did not keep them, or no cage to tell what was applied
    bound = np.asarray(obj.shapedeform[CUTOUT_KEY], dtype=np.float64).reshape(-1, 3)
    if len(bound) != len(cutout.vertices):
        return False
    now = np.empty(len(cutout.vertices) * 3, dtype=np.float32)
    cutout.vertices.foreach_get("co", now)
    expected = transform_points(applied, bound)
    return bool(np.allclose(now.reshape(-1, 3), expected, rtol=0.0, atol=1e-5 * max(np.ptp(bound, axis=0).max(), 1e-9)))


def _attribute_digests(mesh):
    """{name: digest} of the attributes of a cut-out one can edit or add: a UV map's digest is
    of its UVs; any other attribute is told by its name alone ("")."""
    uvs = {layer.name: hashlib.sha1(_loop_uvs(layer).tobytes()).hexdigest() for layer in mesh.uv_layers}
    return {attribute.name: uvs.get(attribute.name, "") for attribute in mesh.attributes
            if attribute.name != "position" and not attribute.name.startswith(".")}  # "." marks selection and such


def _attribute_edits(obj, cutout, uvs_too):
    """What Unbind drops beyond the cut-out's vertices: its UV maps edited (when ``uvs_too``:
    vertices added or deleted change them with no edit of their own), renamed, added or
    deleted, attributes added (colours painted), vertex-group weights; as phrases for a message."""
    lost = []
    bound = obj.shapedeform.get(CUTOUT_ATTRIBUTES)
    if bound is not None:  # bound by a version that kept them
        bound, now = bound.to_dict(), _attribute_digests(cutout)
        uv_maps = {layer.name for layer in cutout.uv_layers}
        lost += _uv_map_edits(bound, {name: digest for name, digest in now.items() if name in uv_maps}, uvs_too)
        added = [name for name in now if name not in uv_maps and name not in bound]
        if added:
            lost.append(f"the attributes added to its cut-out ({', '.join(map(repr, added))}: colours and the like; "
                        "Undo brings them back)")
    if obj.vertex_groups and any(vertex.groups for vertex in cutout.vertices):  # bind gives the cut-out no weights
        lost.append("the vertex-group weights of its cut-out (the picture's quad keeps its own; Undo brings them back)")
    return lost


def _uv_map_edits(bound, now, uvs_too):
    """Phrases for the cut-out's UV maps edited (when ``uvs_too``), renamed, added or deleted
    since Bind, from the digests Bind kept (``bound``, every attribute; UV maps' not empty) and
    the UV maps' now (``now``)."""
    edited = [name for name, digest in now.items() if name in bound and digest != bound[name]]
    deleted = [name for name, digest in bound.items() if digest and name not in now]
    added = [name for name in now if name not in bound]
    # A UV map renamed is one deleted and one added with the same UVs.
    added_by_uvs = {now[name]: name for name in added}
    renamed = {old: added_by_uvs.pop(bound[old]) for old in deleted if bound[old] in added_by_uvs}
    deleted = [name for name in deleted if name not in renamed]
    added = [name for name in added if name not in renamed.values()]
    lost = []
    if edited and uvs_too:
        lost.append(f"the edits of its cut-out's UV maps ({', '.join(map(repr, edited))}; the picture's quad "
                    "keeps its own; Undo brings them back)")
    if renamed:
        pairs = ", ".join(f"{old!r} as {new!r}" for old, new in renamed.items())
        lost.append(f"the UV maps renamed on its cut-out ({pairs}; the picture's quad keeps their names: "
                    "rename them there again)")
    if added:
        lost.append(f"the UV maps added to its cut-out ({', '.join(map(repr, added))}; Undo brings them back)")
    if deleted:
        lost.append(f"the UV maps deleted from its cut-out ({', '.join(map(repr, deleted))}; the picture's quad "
                    "still has them: delete them there again)")
    return lost


def restore_legacy(obj):
    """Write an older version's saved rest points back (see :mod:`.sources`)."""
    # An older version's image plane wrote poses into the cut-out, which goes with the quad's return.
    return [] if obj.shapedeform.original_data is not None else mesh_source.restore_legacy(obj)
