# SPDX-License-Identifier: GPL-3.0-or-later
"""Rendering in tests, headless: a camera over a flat scene, a render read back as pixels, and
which pixels two parts of an evaluated mesh both cover."""

import bpy
import numpy as np
import shapely


def camera_over(centre, width, perspective=False):
    """A camera looking down -Z at ``centre`` (x, y), seeing ``width`` across."""
    data = bpy.data.cameras.new("Camera")
    camera = bpy.data.objects.new("Camera", data)
    bpy.context.scene.collection.objects.link(camera)
    if perspective:
        data.type, data.lens, data.sensor_width = "PERSP", 50.0, 36.0
        height = width * data.lens / data.sensor_width  # so the view is ``width`` wide at z = 0
    else:
        data.type, data.ortho_scale, height = "ORTHO", width, 10.0
    camera.location = (centre[0], centre[1], height)
    bpy.context.scene.camera = camera
    return camera


def flat_material(name, colour):
    """A material of one flat colour in Workbench (its viewport colour) and Cycles (emission)."""
    material = bpy.data.materials.new(name)
    material.diffuse_color = colour
    if material.node_tree is None:  # Blender 5 materials always have nodes
        material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.clear()
    emission = nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = colour
    output = nodes.new("ShaderNodeOutputMaterial")
    links.new(emission.outputs[0], output.inputs["Surface"])
    return material


def eevee():
    """EEVEE's engine name: ``BLENDER_EEVEE_NEXT`` on Blender 4.2-4.5, ``BLENDER_EEVEE`` since 5.0."""
    names = {item.identifier for item in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in names else "BLENDER_EEVEE"


def render(path, engine="BLENDER_WORKBENCH", size=160, samples=8, color_type="MATERIAL"):
    """Render the scene's camera to ``path`` and return its pixels, (size, size, 4), rows from
    the bottom. Workbench shows material colours (or textures) flat; Cycles runs on the CPU;
    ``engine="EEVEE"`` is EEVEE under its name in this Blender, at one sample (it renders under
    software OpenGL headless, about 2 s a picture after its shaders compile)."""
    scene = bpy.context.scene
    scene.render.engine = eevee() if engine == "EEVEE" else engine
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    if engine == "BLENDER_WORKBENCH":
        shading = scene.display.shading
        shading.light, shading.color_type = "FLAT", color_type
        shading.background_type = "WORLD"
    elif engine == "EEVEE":
        scene.eevee.taa_render_samples = 1
    else:
        scene.cycles.device, scene.cycles.samples = "CPU", samples
        scene.cycles.use_denoising = False
    world = scene.world or bpy.data.worlds.new("World")
    scene.world = world
    world.color = (0.0, 0.0, 0.0)
    scene.render.filepath = str(path)
    scene.render.image_settings.file_format = "PNG"
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    pixels = np.empty(size * size * 4, np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(size, size, 4)


def animation_frame(frame, folder, name, size=48):
    """Render ``frame`` as Render Animation does on a farm (from frame 1: the render sets and
    evaluates the frame itself, in a depsgraph of its own) with :func:`render`'s settings, and
    return its pixels, (size, size, 4)."""
    scene = bpy.context.scene
    scene.frame_set(1)
    scene.frame_start = scene.frame_end = frame
    render(folder / "settings.png", size=size)  # the engine and its settings
    scene.render.filepath = str(folder / f"{name}_")
    bpy.ops.render.render(animation=True)
    image = bpy.data.images.load(str(folder / f"{name}_{frame:04d}.png"))
    pixels = np.empty(size * size * 4, np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(size, size, 4)


def pixel_centres(camera, size):
    """World (x, y) at the centre of each pixel of an orthographic camera's render, (size, size, 2)."""
    width = camera.data.ortho_scale
    steps = (np.arange(size) + 0.5) / size * width - width / 2
    xs, ys = np.meshgrid(camera.location.x + steps, camera.location.y + steps)
    return np.stack([xs, ys], axis=2)


def covered(obj, faces):
    """The area the evaluated faces of ``obj`` in ``faces`` (boolean per face) cover, world XY."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    mesh.calc_loop_triangles()
    world = np.array(obj.matrix_world)
    points = np.array([world[:3, :3] @ v.co + world[:3, 3] for v in mesh.vertices])[:, :2]
    triangles = [(t.vertices[:], t.polygon_index) for t in mesh.loop_triangles]
    evaluated.to_mesh_clear()
    polygons = [shapely.Polygon(points[list(v)]) for v, face in triangles if faces[face]]
    return shapely.union_all([p for p in polygons if p.area > 0])


def overlap_pixels(camera, size, first, second, margin):
    """Pixels (size, size) bool whose centres lie inside both areas, at least ``margin`` inside."""
    overlap = shapely.intersection(first, second).buffer(-margin)
    centres = pixel_centres(camera, size)
    return shapely.contains_xy(overlap, centres[..., 0], centres[..., 1])
