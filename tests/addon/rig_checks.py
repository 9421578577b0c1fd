# SPDX-License-Identifier: GPL-3.0-or-later
"""Checks shared by the rig tests: read back what Blender evaluated and judge a pose."""

import bpy
import numpy as np


def smallest_angles(points, tris):
    a, b, c = (points[tris[:, k]] for k in range(3))
    def angle(p, q, r):
        u, v = q - p, r - p
        cos = np.einsum('ij,ij->i', u, v) / np.maximum(np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1), 1e-300)
        return np.arccos(np.clip(cos, -1, 1))
    return np.minimum.reduce([angle(a, b, c), angle(b, c, a), angle(c, a, b)])


def world(obj, local):
    m = np.array(obj.matrix_world)
    return tuple(m[:3, :3] @ np.asarray(local, float) + m[:3, 3])


def select_only(obj):
    """Select ``obj`` alone and make it active, as a click in the viewport does."""
    for other in bpy.context.selected_objects:
        other.select_set(False)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj


def add_handle(obj, location):
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.add_handle(location=location) == {"FINISHED"}
    handle = obj.shapedeform.handles[-1].object
    bpy.context.view_layer.update()
    return handle


def bind_with_handles(obj, *points):
    """Bind ``obj`` and add a handle at each of ``points`` (local, (3,)); returns the handles."""
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    return [add_handle(obj, world(obj, point)) for point in points]


def mesh_points(obj, mesh=None):
    mesh = obj.data if mesh is None else mesh
    flat = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.attributes["position"].data.foreach_get("vector", flat)
    return flat.reshape(-1, 3)


def evaluated_vertices(obj):
    """The vertices (n, 3) of the mesh Blender evaluates ``obj`` to (a curve's or text's too)."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    points = np.array([v.co for v in mesh.vertices])
    evaluated.to_mesh_clear()
    return points


def refine(shapedeform, obj, level=None):
    """The Refine input of ``obj``'s Shape Deform modifier, set first when ``level`` is given
    (``shapedeform``: the add-on's module, as the ``addon`` fixture gives it)."""
    modifier = shapedeform.rig_format.modifiers_of(obj)[0]
    identifier = shapedeform.nodes.input_identifiers(modifier.node_group)["Refine"]
    if level is not None:
        shapedeform.compat.set_modifier_input(modifier, identifier, level)
        obj.update_tag()
        bpy.context.view_layer.update()
    return shapedeform.compat.modifier_input(modifier, identifier)


def evaluated_mesh_points(obj):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return mesh_points(obj, obj.evaluated_get(depsgraph).data)


def attribute_vectors(attributes, name, count):
    flat = np.empty(count * 3, np.float32)
    attributes[name].data.foreach_get("vector", flat)
    return flat.reshape(-1, 3)


def evaluated_curve_points(obj, handles=True):
    """Control points of an evaluated curve (its modifiers applied), then with ``handles`` its
    left and right handles: (p, 3) float32, in the order the curve's splines hold them."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    geometry = obj.evaluated_get(depsgraph).evaluated_geometry()  # owns what it hands out
    curves = geometry.curves
    count = len(curves.points)
    names = ("position", "handle_left", "handle_right") if handles else ("position",)
    return np.concatenate([attribute_vectors(curves.attributes, name, count) for name in names])


def drawing_points(drawing):
    """Stroke points (p, 3) float32 of a grease-pencil drawing."""
    attribute = drawing.attributes["position"]
    flat = np.empty(len(attribute.data) * 3, np.float32)
    attribute.data.foreach_get("vector", flat)
    return flat.reshape(-1, 3)


def evaluated_drawing_points(obj, layer=None):
    """Stroke points (p, 3) float32 of the evaluated drawings on the current frame (every layer,
    bottom to top, or only ``layer``), modifiers applied."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    geometry = obj.evaluated_get(depsgraph).evaluated_geometry()  # owns what it hands out
    data = geometry.grease_pencil
    layers = [data.layers[layer]] if layer is not None else list(data.layers)
    found = [drawing_points(l.current_frame().drawing) for l in layers if l.current_frame() is not None]
    return np.concatenate(found) if found else np.empty((0, 3), np.float32)


def cage(obj):
    """The cage object of ``obj``'s rig."""
    return obj.shapedeform.cage


def triangles(obj):
    mesh = obj.data
    mesh.calc_loop_triangles()
    flat = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", flat)
    return flat.reshape(-1, 3)


def signed_areas(points2, tris):
    a, b, c = (points2[tris[:, k]] for k in range(3))
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def plane_axes(normal):
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(normal, [0.3, 0.5, 0.8])
    u /= np.linalg.norm(u)
    return np.stack([u, np.cross(normal, u)])


def area(obj, points, normal=(0, 0, 1.0)):
    flat = points @ plane_axes(normal).T
    return float(np.abs(signed_areas(flat, triangles(obj)).sum()))


# Most a point is lifted off its plane toward the front, per unit of the distance it moved
# (solver/rigging/depth.py: 0.01 of the size per size moved), with float32 rounding.
DEPTH_PER_MOVE = 0.0101


def assert_in_front_only(rest, posed, normal, size):
    """Every point is on its plane or lifted toward the front by the depth rule, no more."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    height = (posed - rest) @ normal
    moved = np.linalg.norm((posed - rest) - height[:, None] * normal, axis=1)
    assert height.min() > -1e-5 * size, "points went behind the plane"
    assert height.max() < DEPTH_PER_MOVE * moved.max() + 1e-5 * size, "points left the plane"


def assert_posed(obj, rest, posed, normal, reached=(), exact=True):
    """Handles reached, the shape followed, no triangle flipped, every point in the plane (or
    lifted a little toward the front, where it may overlap the rest of the shape)."""
    assert np.all(np.isfinite(posed))
    size = float(np.linalg.norm(np.ptp(rest, axis=0)))
    assert np.abs(posed - rest).max() > 1e-3 * size, "the shape did not move"
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    assert_in_front_only(rest, posed, normal, size)
    tris = triangles(obj)
    flat_rest, flat_posed = (p @ plane_axes(normal).T for p in (rest, posed))
    before, after = signed_areas(flat_rest, tris), signed_areas(flat_posed, tris)
    # Slivers (a smallest angle under a degree, as in text fills) flip invisibly; judge the rest.
    keep = smallest_angles(flat_rest, tris) > np.radians(1.0)
    assert np.all(np.sign(before[keep]) == np.sign(after[keep])), f"{int((np.sign(before[keep]) != np.sign(after[keep])).sum())} triangles flipped"
    to_local = np.linalg.inv(np.array(obj.matrix_world))
    for location, handle in reached:
        start = to_local[:3, :3] @ np.asarray(location) + to_local[:3, 3]
        vertex = np.argmin(np.linalg.norm(rest - start, axis=1))
        goal = to_local @ np.append(np.array(handle.matrix_world.translation), 1.0)
        tolerance = 1e-5 * size if exact else 0.02 * size
        miss = posed[vertex] - goal[:3]
        miss -= (miss @ normal) * normal  # in the plane: the depth lift is not a miss
        assert np.linalg.norm(miss) < tolerance, "the handle's vertex did not follow it"


def snapshot():
    """Names of all data-blocks, with the mesh positions: to check nothing changed."""
    state = {}
    for attribute in ("objects", "meshes", "curves", "collections", "grease_pencils"):
        collection = getattr(bpy.data, attribute, None)
        if collection is not None:
            state[attribute] = sorted(item.name for item in collection)
    for mesh in bpy.data.meshes:
        coordinates = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", coordinates)
        state[f"mesh {mesh.name}"] = (coordinates.tobytes(), sorted(a.name for a in mesh.attributes))
    return state


def save_png(path, pixels):
    """Save ``pixels`` (h, w, 4) float32, rows bottom up, as a PNG with alpha at ``path``."""
    height, width = pixels.shape[:2]
    image = bpy.data.images.new(path.stem, width, height, alpha=True)
    image.pixels.foreach_set(np.ascontiguousarray(pixels, dtype=np.float32).ravel())
    image.filepath_raw = str(path)
    image.file_format = "PNG"
    image.save()
    bpy.data.images.remove(image)


def import_picture(folder, name, pixels, **options):
    """Save ``pixels`` (h, w, 4) float32 as ``<folder>/<name>.png`` and import it as a plane
    (Import Images as Planes, with its ``options``); returns the plane."""
    save_png(folder / f"{name}.png", pixels)
    result = bpy.ops.image.import_as_mesh_planes(files=[{"name": f"{name}.png"}], directory=str(folder), **options)
    assert result == {"FINISHED"}
    return bpy.context.active_object
