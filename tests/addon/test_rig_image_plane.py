# SPDX-License-Identifier: GPL-3.0-or-later
"""Rigging an image with alpha imported as a plane: the quad becomes a cut-out."""

import bpy
from mathutils import Matrix, Vector
import numpy as np
import pytest

import rig_checks as checks

W, H = 64, 48


def import_picture(folder):
    """A PNG with alpha (a disc and a block, colours that vary with x and y), imported as a plane."""
    yy, xx = np.mgrid[:H, :W]
    pixels = np.zeros((H, W, 4), np.float32)
    pixels[..., 0], pixels[..., 1], pixels[..., 2] = xx / W, yy / H, 0.5
    pixels[..., 3] = (((xx - 40) ** 2 + (yy - 22) ** 2) < 15 ** 2) | ((xx > 8) & (xx < 30) & (yy > 16) & (yy < 28))
    return checks.import_picture(folder, "picture", pixels), pixels


def uv_of_points(mesh, name=None):
    """Each vertex's UV in the UV map ``name`` (the active one by default; every loop of a vertex
    has the same UV on the cut-out)."""
    loops = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", loops)
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    (mesh.uv_layers.active if name is None else mesh.uv_layers[name]).data.foreach_get("uv", uv)
    result = np.zeros((len(mesh.vertices), 2))
    result[loops] = uv.reshape(-1, 2)
    return result


def test_a_coarse_cutout_still_shows_every_visible_pixel(addon, tmp_path):
    """At a low Graph Density (or a large picture) the cut-out, which is the rig's graph, was
    simplified to its spacing: a 1-pixel line and a 2 x 2 dot fell off it and stopped rendering,
    and the outline's pixels lost slivers (QA: all 3,071 pixels of a line at 4,096 pixels).
    Every visible pixel now lies on the cut-out, as its UVs show it."""
    import shapely

    yy, xx = np.mgrid[:768, :1024]
    pixels = np.zeros((768, 1024, 4), np.float32)
    pixels[..., 3] = (xx - 400) ** 2 + (yy - 400) ** 2 < 300 ** 2
    pixels[60, 150:1000, 3] = pixels[740:742, 900:902, 3] = 1.0
    obj = checks.import_picture(tmp_path, "whisker", pixels)
    obj.shapedeform.density = 20
    bind(obj)
    cutout = obj.data
    cutout.calc_loop_triangles()
    corners = np.empty(3 * len(cutout.loop_triangles), np.int32)
    cutout.loop_triangles.foreach_get("vertices", corners)
    shown = uv_of_points(cutout)[corners.reshape(-1, 3)] * (1024, 768)
    shape = shapely.union_all(shapely.polygons(shown)).buffer(1e-3)
    visible = pixels[..., 3] > 0
    boxes = shapely.box(xx[visible], yy[visible], xx[visible] + 1, yy[visible] + 1)
    assert shapely.contains(shape, boxes).all(), int((~shapely.contains(shape, boxes)).sum())


@pytest.mark.parametrize("mirrored", [False, True])
def test_the_cutout_faces_the_way_the_quad_faces(addon, tmp_path, mirrored):
    """A plane mirrored (S X -1, Apply Scale) keeps its face turned the other way; its cut-out
    faced the plane's normal whatever the quad did, and vanished under backface culling (QA:
    257 pixels before Bind, 0 after)."""
    obj, _ = import_picture(tmp_path)
    if mirrored:
        checks.select_only(obj)
        obj.scale.x = -1.0
        assert bpy.ops.object.transform_apply(location=False, rotation=False, scale=True) == {"FINISHED"}
    facing = np.array(obj.data.polygons[0].normal)
    bind(obj)
    normals = np.empty(3 * len(obj.data.polygons), np.float32)
    obj.data.polygons.foreach_get("normal", normals)
    assert np.all(normals.reshape(-1, 3) @ facing > 0.99)


def test_image_plane_becomes_a_cutout_that_maps_the_image_exactly(addon, tmp_path):
    obj, pixels = import_picture(tmp_path)
    obj.rotation_euler = (1.2, 0.0, 0.3)  # Blender's importer stands pictures up; any angle works
    bpy.context.view_layer.update()
    quad = obj.data
    quad_points = checks.mesh_points(obj).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert obj.data != quad and obj.shapedeform.kind == "IMAGE"
    cutout = obj.data
    points = checks.mesh_points(obj)
    # UVs map the image exactly as the quad did: the quad maps x in [-w/2, w/2] to u in [0, 1].
    lo, hi = quad_points.min(axis=0), quad_points.max(axis=0)
    expected = (points[:, :2] - lo[:2]) / (hi[:2] - lo[:2])
    np.testing.assert_allclose(uv_of_points(cutout), expected, atol=1e-5)
    # The cut-out covers every visible pixel and not much more (a margin of about a pixel,
    # which on this small picture is a fifth of its area).
    visible = pixels[..., 3] > 0
    area = checks.area(obj, points) / np.prod((hi - lo)[:2])
    assert visible.mean() < area < 1.3 * visible.mean()
    tris = checks.triangles(obj)
    uv = uv_of_points(cutout)
    yy, xx = np.nonzero(visible)
    centres = np.stack([(xx + 0.5) / W, (yy + 0.5) / H], axis=1)
    a, b, c = (uv[tris[:, k]] for k in range(3))
    covered = np.zeros(len(centres), bool)
    for start in range(0, len(tris), 256):  # chunked point-in-triangle test
        sl = slice(start, start + 256)
        d = lambda p, q: (q[None, :, 0] - p[None, :, 0]) * (centres[:, None, 1] - p[None, :, 1]) - \
            (q[None, :, 1] - p[None, :, 1]) * (centres[:, None, 0] - p[None, :, 0])
        s1, s2, s3 = d(a[sl], b[sl]), d(b[sl], c[sl]), d(c[sl], a[sl])
        covered |= (((s1 >= -1e-9) & (s2 >= -1e-9) & (s3 >= -1e-9)) | ((s1 <= 1e-9) & (s2 <= 1e-9) & (s3 <= 1e-9))).any(axis=1)
    assert covered.all(), f"{(~covered).sum()} visible pixels fall outside the cut-out"

    left = checks.world(obj, points[np.argmin(points[:, 0])])
    right = checks.world(obj, points[np.argmax(points[:, 0])])
    checks.add_handle(obj, left)
    handle = checks.add_handle(obj, right)
    handle.location.y += 0.3  # in the picture's own space: handles are parented to it
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(obj)
    checks.assert_posed(obj, points, posed, normal=np.array([0, 0, 1.0]), reached=[(right, handle)])

    name = obj.name
    path = str(tmp_path / "picture.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects[name]
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert len(obj.data.vertices) == 4 and obj.shapedeform.original_data is None
    assert checks.mesh_points(obj).tobytes() == quad_points.tobytes()
    assert len(bpy.data.meshes) == 1 and len(bpy.data.objects) == 1


def test_unbind_says_when_it_drops_edits_made_to_the_cut_out(addon, tmp_path):
    """Unbind gives the image plane's quad back; where the cut-out was edited in Edit Mode, it
    says the edits go with it (they went silently). An applied rotation and scale is not an edit."""
    import bmesh

    obj, _ = import_picture(tmp_path)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    obj.rotation_euler.z = 0.4
    obj.scale = (2.0, 2.0, 2.0)
    assert bpy.ops.object.transform_apply(location=False, rotation=True, scale=True) == {"FINISHED"}
    binding = addon.shapedeform_addon.binding
    assert binding.unbind(obj) == []

    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="EDIT")
    edited = bmesh.from_edit_mesh(obj.data)
    bmesh.ops.delete(edited, geom=list(edited.verts)[: len(edited.verts) // 2], context="VERTS")
    bmesh.update_edit_mesh(obj.data)
    bpy.ops.object.mode_set(mode="OBJECT")
    lost = binding.unbind(obj)
    assert len(lost) == 1 and "edits of its cut-out" in lost[0]
    assert len(obj.data.vertices) == 4  # the quad is back


@pytest.mark.parametrize("height, width", [(1, 64), (64, 1)])
def test_a_picture_one_pixel_thin_is_cut_out(addon, tmp_path, height, width):
    """A line one pixel thin has something to deform (it was refused as having no pixels, as
    if its file were missing); a single pixel is refused as such."""
    obj = checks.import_picture(tmp_path, "line", np.ones((height, width, 4), np.float32))
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert obj.shapedeform.kind == "IMAGE"
    dot = checks.import_picture(tmp_path, "dot", np.ones((1, 1, 4), np.float32))
    bpy.context.view_layer.objects.active = dot
    with pytest.raises(RuntimeError, match="'dot.png' is a single pixel"):
        bpy.ops.shapedeform.bind()


def test_the_cut_out_is_what_the_plane_shows(addon, tmp_path):
    """A plane whose UVs frame the right half of a picture (a sprite sheet's frame) is cut out
    within itself (the cropped-away left disc appeared beside it); of several image nodes, the
    one wired to the shader's alpha is cut out (the first one was, opaque: the whole quad); a
    material given to the cut-out is named as dropped by Unbind."""
    yy, xx = np.mgrid[:32, :64]
    pixels = np.ones((32, 64, 4), np.float32)
    pixels[..., 3] = (((xx - 16) ** 2 + (yy - 16) ** 2) < 10 ** 2) | (((xx - 48) ** 2 + (yy - 16) ** 2) < 10 ** 2)
    obj = checks.import_picture(tmp_path, "sheet", pixels)
    mesh = obj.data
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers.active.data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2)
    uv[:, 0] = 0.5 + 0.5 * uv[:, 0]  # the right half of the picture over the whole plane
    mesh.uv_layers.active.data.foreach_set("uv", uv.ravel())
    material = obj.active_material
    opaque = bpy.data.images.new("Opaque", 8, 8, alpha=True)
    opaque.pixels.foreach_set(np.ones(8 * 8 * 4, np.float32))
    tree = material.node_tree
    tree.nodes.new("ShaderNodeTexImage").image = opaque  # unwired
    # The picture's node after it: removed and made again, its links with it.
    picture = next(n for n in tree.nodes if n.type == "TEX_IMAGE" and n.image != opaque)
    links = [(out.name, link.to_socket) for out in picture.outputs for link in out.links]
    image = picture.image
    tree.nodes.remove(picture)
    again = tree.nodes.new("ShaderNodeTexImage")
    again.image = image
    for name, target in links:
        tree.links.new(again.outputs[name], target)
    assert [n.image for n in tree.nodes if n.type == "TEX_IMAGE"] == [opaque, image]
    quad = checks.mesh_points(obj).copy()
    low, high = quad.min(axis=0), quad.max(axis=0)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    cut = checks.mesh_points(obj)
    assert np.all(cut[:, :2] >= low[:2] - 1e-5) and np.all(cut[:, :2] <= high[:2] + 1e-5)
    # One disc (the right one) filling the middle of the plane: far less than the whole quad.
    area = np.ptp(cut[:, 0]) * np.ptp(cut[:, 1])
    assert area < 0.8 * np.ptp(quad[:, 0]) * np.ptp(quad[:, 1])

    obj.data.materials.append(bpy.data.materials.new("Added"))
    lost = addon.shapedeform_addon.binding.unbind(obj)
    assert len(lost) == 1 and "materials given to its cut-out" in lost[0]


def filter_weights(interpolation, offsets):
    """Weight of a texel at ``offsets`` (texels from its centre) in Blender's filtering: linear
    or the cubic B-spline (Cubic; Smart renders as Cubic)."""
    d = np.abs(offsets)
    if interpolation == "Linear":
        return np.maximum(1.0 - d, 0.0)
    return np.where(d < 1.0, (4.0 - 6.0 * d ** 2 + 3.0 * d ** 3) / 6.0, np.maximum(2.0 - d, 0.0) ** 3 / 6.0)


def inside_triangles(points, triangles):
    """(n,) bool: whether each of ``points`` (n, 2) lies in any of ``triangles`` (t, 3, 2)."""
    a, b, c = (triangles[:, k][None] for k in range(3))
    p = points[:, None]

    def side(u, v):
        return (v[..., 0] - u[..., 0]) * (p[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (p[..., 0] - u[..., 0])

    s = np.stack([side(a, b), side(b, c), side(c, a)])
    return (((s >= -1e-9).all(axis=0)) | ((s <= 1e-9).all(axis=0))).any(axis=1)


@pytest.mark.parametrize("interpolation", ["Linear", "Cubic", "Smart"])
def test_the_cut_out_covers_what_the_pictures_filter_shows(addon, tmp_path, interpolation):
    """Every point where the filtered picture's alpha is visible (1/255 or more) is inside the
    cut-out: Cubic filtering (Smart renders as Cubic) reaches 1.5 texels past a visible texel's
    edge, Linear 0.5 (with Cubic up to 1.3% alpha was clipped at Bind, 1 in 255 at 0.2 texels
    outside the cut-out)."""
    obj, pixels = import_picture(tmp_path)
    picture_node = next(n for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE")
    picture_node.interpolation = interpolation
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    texels = uv_of_points(obj.data) * (W, H)
    triangles = texels[checks.triangles(obj)]
    xs, ys = np.arange(0.0, W, 0.125), np.arange(0.0, H, 0.125)
    rows = filter_weights(interpolation, ys[:, None] - (np.arange(H) + 0.5))
    columns = filter_weights(interpolation, xs[:, None] - (np.arange(W) + 0.5))
    alpha = rows @ pixels[..., 3] @ columns.T
    faint = (alpha >= 1.0 / 255.0) & (alpha < 0.999)  # the edge: the inside is covered anyway
    points = np.stack(np.meshgrid(xs, ys), axis=-1)[faint]
    clipped = ~inside_triangles(points, triangles)
    assert not clipped.any(), (f"{clipped.sum()} points of the picture's edge are outside the cut-out, alpha up to "
                               f"{alpha[faint][clipped].max():.4f}")


@pytest.mark.parametrize("interpolation", ["Linear", "Cubic", "Closest"])
def test_the_cut_out_of_a_repeating_picture_covers_the_far_edges_filtered_in(addon, tmp_path, interpolation):
    """With Extension Repeat, filtering blends each edge of the picture with the opposite one:
    pixels touching the right and top edges show faintly along the left and bottom ones, and
    the cut-out, clipped to the picture, left 50-240 such pixels out (QA). Closest blends
    nothing in, and the cut-out gets no band there."""
    yy, xx = np.mgrid[:H, :W]
    pixels = np.zeros((H, W, 4), np.float32)
    pixels[..., 3] = ((xx >= W - 6) & (yy > 10) & (yy < 30)) | ((yy >= H - 4) & (xx > 20) & (xx < 40))
    obj = checks.import_picture(tmp_path, "tiles", pixels)
    picture_node = next(n for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE")
    picture_node.interpolation, picture_node.extension = interpolation, "REPEAT"
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    texels = uv_of_points(obj.data) * (W, H)
    triangles = texels[checks.triangles(obj)]
    if interpolation == "Closest":
        assert not inside_triangles(np.array([[0.25, 20.0], [30.0, 0.25]]), triangles).any()
        return
    xs, ys = np.arange(0.0, W, 0.125), np.arange(0.0, H, 0.125)

    def wrapped(samples, count):  # offsets from every texel's centre, the nearer way round
        return (samples[:, None] - (np.arange(count) + 0.5) + 0.5 * count) % count - 0.5 * count

    alpha = filter_weights(interpolation, wrapped(ys, H)) @ pixels[..., 3] @ filter_weights(interpolation,
                                                                                             wrapped(xs, W)).T
    faint = (alpha >= 1.0 / 255.0) & (alpha < 0.999)
    points = np.stack(np.meshgrid(xs, ys), axis=-1)[faint]
    assert (points[:, 0] < 1.0).any() and (points[:, 1] < 1.0).any()  # the far edges show near the origin
    clipped = ~inside_triangles(points, triangles)
    assert not clipped.any(), (f"{clipped.sum()} points of the picture's edge are outside the cut-out, alpha up to "
                               f"{alpha[faint][clipped].max():.4f}")


@pytest.mark.parametrize("extension, moved", [("REPEAT", "a tile over"), ("REPEAT", "mirrored"),
                                               ("REPEAT", "a hair past 0"), ("MIRROR", "a tile over"),
                                               ("MIRROR", "mirrored")])
def test_a_repeating_picture_is_cut_out_a_whole_tile_over(addon, tmp_path, extension, moved):
    """With Extension Repeat, UVs moved a whole tile (or mirrored, u to -u) show the same
    picture (mirrored), and Bind refused: 'no visible pixel ... in the part its UVs show'. The
    cut-out is that of the picture the UVs show, as where they were. With Extension Mirror, the
    tile next door shows the picture mirrored, so the UVs mirrored show it as it is."""
    reference, _ = import_picture(tmp_path)
    bind(reference)
    expected = checks.mesh_points(reference)
    obj, _ = import_picture(tmp_path)
    next(n for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE").extension = extension
    layer = obj.data.uv_layers.active
    uv = np.empty(2 * len(layer.data), np.float32)
    layer.data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2)
    if moved == "a tile over":
        uv = uv + (1.0, -2.0)
    elif moved == "mirrored":
        uv = uv * (-1.0, 1.0)
    else:  # float32 noise of UVs turned or scaled (review: the window jumped a whole tile)
        uv = np.where(uv < 0.5, uv - 5e-6, uv)
    layer.data.foreach_set("uv", uv.ravel())
    bind(obj)
    shown = checks.mesh_points(obj)
    if (moved != "mirrored") == (extension == "REPEAT"):
        np.testing.assert_allclose(shown, expected, atol=1e-4)
    else:  # the plane shows the picture mirrored about its centre: so is the cut-out's extent
        shown[:, 0] *= -1.0
        np.testing.assert_allclose([shown.min(axis=0), shown.max(axis=0)],
                                   [expected.min(axis=0), expected.max(axis=0)], atol=0.01)


@pytest.mark.parametrize("extension", ["REPEAT", "MIRROR", "CLIP", "EXTEND"])
def test_bind_says_when_the_uvs_repeat_the_picture(addon, tmp_path, capsys, extension):
    """UVs past the square show the picture again where it repeats or mirrors; clipped or
    extended, it shows once, and Bind said it repeated (QA)."""
    obj, _ = import_picture(tmp_path)
    next(n for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE").extension = extension
    mesh = obj.data
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers.active.data.foreach_get("uv", uv)
    mesh.uv_layers.active.data.foreach_set("uv", 2.0 * uv)  # the picture twice each way
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    said = "its UVs show the picture more than once: only the copy in the UV square is cut out"
    assert (said in capsys.readouterr().out) == (extension in {"REPEAT", "MIRROR"})


def test_a_plane_whose_alpha_nothing_reads_is_rigged_whole_however_its_uvs_repeat_the_picture(addon, tmp_path,
                                                                                             capsys):
    """With the picture's Alpha unwired the whole plane renders, the picture repeated by UVs
    past the square: the whole quad is rigged (it was cut to the UV square, a quarter of it),
    and its pixels are not read (a 4,096-pixel square took 2.3 s to bind)."""
    obj, _ = import_picture(tmp_path)
    tree = obj.active_material.node_tree
    image = next(n for n in tree.nodes if n.type == "TEX_IMAGE")
    tree.links.remove(image.outputs["Alpha"].links[0])
    mesh = obj.data
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers.active.data.foreach_get("uv", uv)
    mesh.uv_layers.active.data.foreach_set("uv", 2.0 * uv)  # the picture twice each way
    quad = checks.mesh_points(obj)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    said = capsys.readouterr().out
    assert "the whole plane is rigged" in said and "only the copy in the UV square" not in said
    lo, hi = quad.min(axis=0), quad.max(axis=0)
    assert checks.area(obj, checks.mesh_points(obj)) == pytest.approx(np.prod((hi - lo)[:2]), rel=1e-6)
    np.testing.assert_allclose(uv_of_points(obj.data).max(axis=0), 2.0 * uv.reshape(-1, 2).max(axis=0), atol=1e-6)


def test_an_image_sequence_is_cut_out_around_every_frame(addon, tmp_path):
    """A plane playing an image sequence (a disc moving across) is cut out around all the frames
    it plays (it was cut out around the frame last loaded: every other frame was clipped, one to
    nothing); one whose frames are all missing is refused by name (it was rigged as a bare quad)."""
    yy, xx = np.mgrid[:H, :W]
    for frame, x in ((1, 14), (2, 32), (3, 50)):
        pixels = np.ones((H, W, 4), np.float32)
        pixels[..., 3] = ((xx - x) ** 2 + (yy - 24) ** 2) < 10 ** 2
        checks.save_png(tmp_path / f"walk_{frame:03d}.png", pixels)
    result = bpy.ops.image.import_as_mesh_planes(files=[{"name": f"walk_{f:03d}.png"} for f in (1, 2, 3)],
                                                 directory=str(tmp_path), image_sequence=True)
    assert result == {"FINISHED"}
    obj = bpy.context.active_object
    bpy.context.scene.frame_set(1)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert obj.shapedeform.kind == "IMAGE"
    u = uv_of_points(obj.data)[:, 0] * W
    assert u.min() < 14 - 9 and u.max() > 50 + 9  # both outer discs inside
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}

    image = next(n.image for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE")
    image.filepath = str(tmp_path / "gone_001.png")
    image.reload()
    with pytest.raises(RuntimeError, match="no frame of its image sequence 'walk_001.png' was found"):
        bpy.ops.shapedeform.bind()
    assert not obj.shapedeform.is_bound


def test_a_plane_whose_picture_is_missing_is_refused(addon, tmp_path):
    obj, _ = import_picture(tmp_path)
    image = next(n.image for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE")
    image.filepath = str(tmp_path / "gone.png")
    image.reload()
    with pytest.raises(RuntimeError, match="has no pixels \\(is the file missing\\?\\)"):
        bpy.ops.shapedeform.bind()
    assert not obj.shapedeform.is_bound and len(obj.data.vertices) == 4


def test_a_movie_plane_is_rigged_whole(addon, tmp_path, capsys):
    """A movie's frames cannot be read one by one from Python: its plane is rigged whole, and
    Bind says so (the cut-out was the last frame shown's, clipping the others)."""
    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    scene.render.film_transparent = True
    scene.frame_start, scene.frame_end = 1, 2
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5.0 and later
        settings.media_type = "VIDEO"
    settings.file_format = "FFMPEG"
    scene.render.ffmpeg.format, scene.render.ffmpeg.codec = "QUICKTIME", "PNG"
    settings.color_mode = "RGBA"
    scene.render.filepath = str(tmp_path / "ball_")
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera, camera.location = camera, (0.0, 0.0, 3.0)
    bpy.ops.mesh.primitive_plane_add(size=0.5)  # a square in the middle of each frame
    bpy.ops.render.render(animation=True)
    movie = next(tmp_path.glob("ball_*"))
    assert bpy.ops.image.import_as_mesh_planes(files=[{"name": movie.name}], directory=str(tmp_path)) == {"FINISHED"}
    obj = bpy.context.active_object
    quad = checks.mesh_points(obj).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert obj.shapedeform.kind == "IMAGE"
    assert "is a movie: its whole frame is rigged" in capsys.readouterr().out
    cut = checks.mesh_points(obj)
    np.testing.assert_allclose(np.ptp(cut, axis=0), np.ptp(quad, axis=0), atol=1e-5)


@pytest.mark.parametrize("how", ["apply", "CURVE", "GREASEPENCIL", "copy"])
def test_a_pose_made_the_planes_own_stays_on_unbind(addon, tmp_path, capsys, how):
    """Applying the rig's modifier or converting the plane makes the pose its own, as the status
    bar says: Unbind keeps it (it put the quad back over an applied pose, saying Edit Mode edits
    were lost, and raised on a plane converted to a curve or a drawing, whose rig then could
    never be removed). A copy made by Convert with Keep Original is a plain object (it counted as
    following the rig, and could not be bound)."""
    obj, _ = import_picture(tmp_path)
    _, handle = checks.bind_with_handles(obj, (-0.44, -0.04, 0.0), (0.17, -0.04, 0.0))
    handle.location.y += 0.2
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(obj).copy()
    checks.select_only(obj)
    if how == "apply":
        assert bpy.ops.object.modifier_apply(modifier=obj.modifiers[0].name) == {"FINISHED"}
    elif how == "copy":
        assert bpy.ops.object.convert(target="MESH", keep_original=True) == {"FINISHED"}
        copy = bpy.context.active_object
        assert copy != obj
        bpy.context.view_layer.update()
        assert not copy.shapedeform.is_bound and not copy.modifiers
        np.testing.assert_allclose(checks.mesh_points(copy), posed, atol=1e-5)
        checks.select_only(obj)
    else:
        assert bpy.ops.object.convert(target=how) == {"FINISHED"}
    bpy.context.view_layer.update()
    capsys.readouterr()
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert not obj.shapedeform.is_bound
    assert "could not" not in capsys.readouterr().out
    assert not any(o.shapedeform.rig == obj for o in bpy.data.objects)
    if how == "apply":
        np.testing.assert_allclose(checks.mesh_points(obj), posed, atol=1e-6)
    elif how == "copy":
        assert len(obj.data.vertices) == 4  # the owner's rig, unbound as usual: its quad is back
        checks.select_only(copy)
        assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    else:
        assert obj.type == how


@pytest.mark.parametrize("how", ["with handles", "alone", "linked"])
def test_a_duplicate_gets_a_rest_quad_of_its_own(addon, tmp_path, how):
    """Shift+D of a bound plane, with its handles (a rig of its own) or alone (it follows the
    rig, and is released when the original is unbound): each plane gets its own quad back, so scaling the
    copy's leaves the original's as imported (both shared one quad: the original's corners came
    back at +-1.333 x +-1 instead of +-0.667 x +-0.5). Alt+D shares the cut-out, and so the quad."""
    from mathutils import Matrix

    obj, _ = import_picture(tmp_path)
    quad = checks.mesh_points(obj).copy()
    handles = checks.bind_with_handles(obj, (-0.44, -0.04, 0.0), (0.17, -0.04, 0.0))
    checks.select_only(obj)
    if how != "alone":
        for handle in handles:
            handle.select_set(True)
    assert bpy.ops.object.duplicate(linked=how == "linked") == {"FINISHED"}
    copy = bpy.context.active_object
    assert copy != obj
    for plane in ((obj,) if how == "alone" else (copy, obj)):  # alone, the copy stops following with its rig
        checks.select_only(plane)
        assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert not copy.shapedeform.is_bound
    if how == "linked":
        assert copy.data == obj.data and len(bpy.data.meshes) == 1
        return
    copy.data.transform(Matrix.Scale(2.0, 4))
    np.testing.assert_array_equal(checks.mesh_points(obj), quad)
    np.testing.assert_array_equal(checks.mesh_points(copy), 2.0 * quad)


@pytest.mark.parametrize("how", ["follower alone", "with the owner and handles"])
def test_a_copy_of_a_follower_gets_a_rest_quad_of_its_own(addon, tmp_path, how):
    """Shift+D of a follower (a Shift+D copy of a bound plane), alone or together with the
    original and its handles: every plane gets a rest quad of its own, so scaling one's quad
    after Unbind leaves every other's as imported (the copy shared the follower's quad: the
    follower's quad came back scaled by both)."""
    from mathutils import Matrix

    obj, _ = import_picture(tmp_path)
    quad = checks.mesh_points(obj).copy()
    handles = checks.bind_with_handles(obj, (-0.44, -0.04, 0.0), (0.17, -0.04, 0.0))
    checks.select_only(obj)
    assert bpy.ops.object.duplicate() == {"FINISHED"}
    follower = bpy.context.active_object
    bpy.context.view_layer.update()
    checks.select_only(follower)
    if how != "follower alone":
        for other in (obj, *handles):
            other.select_set(True)
    assert bpy.ops.object.duplicate() == {"FINISHED"}
    bpy.context.view_layer.update()
    planes = [o for o in bpy.data.objects if o.type == "MESH" and o.shapedeform.is_bound]
    assert len(planes) == (3 if how == "follower alone" else 4)
    is_owner = addon.shapedeform_addon.rig_format.is_owner
    for plane in [plane for plane in planes if is_owner(plane)]:  # their followers are released with them
        checks.select_only(plane)
        assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert not any(plane.shapedeform.is_bound for plane in planes)
    for factor, plane in enumerate(planes, start=2):
        plane.data.transform(Matrix.Scale(factor, 4))
    for factor, plane in enumerate(planes, start=2):
        scale = np.abs(checks.mesh_points(plane)).max() / np.abs(quad).max()
        assert scale == pytest.approx(factor), f"'{plane.name}' shares its quad: scaled {scale:g} times, not {factor}"


def test_a_follower_unbound_before_its_owner_gets_its_quad_back(addon, tmp_path):
    """Shift+D of a bound plane alone follows its rig; unbound while the original is still bound
    it gets its own quad back, as when unbound after the original (it stayed a cut-out of 413
    vertices and its quad copy was deleted), and the original's quad is untouched."""
    from mathutils import Matrix

    obj, _ = import_picture(tmp_path)
    quad = checks.mesh_points(obj).copy()
    checks.bind_with_handles(obj, (-0.44, -0.04, 0.0), (0.17, -0.04, 0.0))
    checks.select_only(obj)
    assert bpy.ops.object.duplicate() == {"FINISHED"}
    copy = bpy.context.active_object
    cutout = copy.data.name
    checks.select_only(copy)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert not copy.shapedeform.is_bound and obj.shapedeform.is_bound
    assert len(copy.data.vertices) == 4, f"the copy stays a cut-out of {len(copy.data.vertices)} vertices"
    np.testing.assert_array_equal(checks.mesh_points(copy), quad)
    assert cutout not in bpy.data.meshes, "the copy's cut-out was left behind"
    copy.data.transform(Matrix.Scale(2.0, 4))
    checks.select_only(obj)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    np.testing.assert_array_equal(checks.mesh_points(obj), quad)


def duplicate(obj, linked):
    """Shift+D (or Alt+D, ``linked``) of ``obj`` alone, settled as the viewport settles it; the copy."""
    checks.select_only(obj)
    assert bpy.ops.object.duplicate(linked=linked) == {"FINISHED"}
    bpy.context.view_layer.update()
    return bpy.context.active_object


def bind(obj):
    checks.select_only(obj)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}


def unbind(obj):
    checks.select_only(obj)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}


def test_a_linked_duplicate_of_one_of_two_planes_bound_on_one_quad_shares_it(addon, tmp_path):
    """Two planes sharing one quad (Alt+D before Bind), each bound, and an Alt+D copy of the
    first (it follows the first's rig, sharing its cut-out): after Unbind all three show the one
    quad, which keeps no stamp. (The quad named one cut-out, the second's once it was bound, so
    the copy got a quad of its own, 'picture.001'; and the first plane's Unbind dropped the name
    while the second was still bound on the quad.)"""
    stamp = addon.shapedeform_addon.rig_format.QUAD_STAMP
    first, _ = import_picture(tmp_path)
    quad = first.data
    second = duplicate(first, linked=True)
    second.location.x += 2.5
    bind(first)
    bind(second)
    copy = duplicate(first, linked=True)
    assert copy.data == first.data and copy.shapedeform.original_data == quad, \
        f"the Alt+D copy keeps '{copy.shapedeform.original_data.name}', not its original's quad"
    unbind(first)  # releases the copy, which follows its rig
    assert stamp in quad, "the quad forgot the second plane's cut-out while it is still bound"
    unbind(second)
    assert first.data == second.data == copy.data == quad
    assert stamp not in quad and len(bpy.data.meshes) == 1, [m.name for m in bpy.data.meshes]


def test_a_renamed_cut_out_keeps_sharing_its_quad(addon, tmp_path):
    """A bound plane's cut-out renamed by hand, shared with an Alt+D copy: the copy still shares
    the plane's quad (it got a copy, as a Shift+D copy does), and Unbind gives both the one quad."""
    obj, _ = import_picture(tmp_path)
    quad = obj.data
    bind(obj)
    copy = duplicate(obj, linked=True)
    obj.data.name = "Renamed"
    copy.location.x += 2.5
    bpy.context.view_layer.update()
    assert copy.shapedeform.original_data == quad
    unbind(obj)
    assert obj.data == copy.data == quad and len(bpy.data.meshes) == 1


@pytest.mark.parametrize("linked", [True, False], ids=["Alt+D", "Shift+D"])
def test_a_quad_stamped_by_an_older_version_is_read(addon, tmp_path, linked):
    """A quad bound by a version that named one cut-out (a string): a linked duplicate of its
    plane shares it, a copy gets a quad of its own, and Unbind leaves it with no stamp."""
    stamp = addon.shapedeform_addon.rig_format.QUAD_STAMP
    obj, _ = import_picture(tmp_path)
    quad = obj.data
    bind(obj)
    quad[stamp] = obj.data.name
    copy = duplicate(obj, linked)
    assert (copy.shapedeform.original_data == quad) == linked
    unbind(obj)
    assert (copy.data == quad) == linked and obj.data == quad and stamp not in quad
    assert stamp not in copy.data


@pytest.mark.parametrize("unbound", ["original", "copy"])
def test_a_copy_given_its_own_materials_by_shift_d_keeps_them_on_unbind(addon, tmp_path, unbound):
    """With Duplicate Data > Material on, Shift+D of a bound plane gives the copy a copy of its
    material; Unbind (of the original, which releases the copy, or of the copy) gives the copy a
    quad with that material, saying nothing (its quad was a copy of the original's, with the
    original's material: Unbind said it could not give back the copy's, which was left with no
    user, lost on saving)."""
    binding = addon.shapedeform_addon.binding
    preferences = bpy.context.preferences.edit
    was = preferences.use_duplicate_material
    preferences.use_duplicate_material = True
    try:
        obj, _ = import_picture(tmp_path)
        material = obj.data.materials[0]
        bind(obj)
        copy = duplicate(obj, linked=False)
    finally:
        preferences.use_duplicate_material = was
    copy_material = copy.data.materials[0]
    assert copy_material not in (None, material)
    lost = binding.unbind(obj if unbound == "original" else copy)
    assert lost == []
    assert len(copy.data.vertices) == 4 and copy.data.materials[:] == [copy_material]
    assert copy_material.users == 1
    if unbound == "copy":
        assert obj.shapedeform.is_bound
        binding.unbind(obj)
    assert obj.data.materials[:] == [material]


@pytest.mark.parametrize("quad_shown_by", ["no other plane", "an unbound plane", "a bound plane",
                                           "a linked duplicate"])
def test_a_material_given_to_the_cut_out_goes_onto_the_quad_no_other_plane_shows(addon, tmp_path, quad_shown_by):
    """A bound plane's cut-out given a material of its own (the material's user-count button):
    Unbind puts it on the quad, unless another plane shows that quad (unbound, or bound on it
    and showing its own cut-out) with its material, which it keeps; Unbind then says the
    cut-out's is dropped. A linked duplicate (Alt+D) following the rig shows the same
    material. (Unbind always dropped it.)"""
    binding = addon.shapedeform_addon.binding
    obj, _ = import_picture(tmp_path)
    quad = obj.data
    material = quad.materials[0]
    other = duplicate(obj, linked=True) if quad_shown_by in ("an unbound plane", "a bound plane") else None
    if other is not None:
        other.location.x += 2.5
    bind(obj)
    if quad_shown_by == "a bound plane":
        bind(other)
    elif quad_shown_by == "a linked duplicate":
        other = duplicate(obj, linked=True)
    own = material.copy()
    obj.data.materials[0] = own
    lost = binding.unbind(obj)
    assert obj.data == quad
    if quad_shown_by in ("an unbound plane", "a bound plane"):
        assert len(lost) == 1 and "materials given to its cut-out" in lost[0] and f"'{other.name}'" in lost[0]
        assert quad.materials[:] == [material]
    else:
        assert lost == [] and quad.materials[:] == [own]
    if quad_shown_by == "a linked duplicate":
        assert other.data == quad


@pytest.mark.parametrize("read_through", ["render-active map", "UV Map node", "UV Map node and Mapping",
                                          "UV Map node in a group"])
def test_every_uv_map_is_kept_and_the_picture_is_cut_out_through_the_one_it_is_read_by(addon, tmp_path,
                                                                                       read_through):
    """A plane with three UV maps: the imported one, a scratch one being edited (active: half the
    imported one, or collapsed to a point) and a copy turned a quarter. The picture is read through
    the render-active map, or through the turned one by a UV Map node. Bind cuts the picture out
    through that map (it used the active one: a quarter of the picture, or refused, 'the points
    lie on one line') and the cut-out keeps every map, each showing what it showed on the quad,
    with the same active and render-active maps (it kept the active one alone: a picture read
    through another rendered nothing). A picture map collapsed is refused by name."""
    obj, pixels = import_picture(tmp_path)
    quad = obj.data
    imported = uv_of_points(quad)
    quad.uv_layers.new(name="Turned")
    loops = np.empty(len(quad.loops), np.int32)
    quad.loops.foreach_get("vertex_index", loops)
    turned = np.stack([1.0 - imported[:, 1], imported[:, 0]], axis=1)
    quad.uv_layers["Turned"].data.foreach_set("uv", turned[loops].astype(np.float32).ravel())
    scratch = 0.5 * imported if read_through == "render-active map" else np.full_like(imported, 0.5)
    quad.uv_layers.new(name="Scratch").data.foreach_set("uv", scratch[loops].astype(np.float32).ravel())
    quad.uv_layers.active = quad.uv_layers["Scratch"]
    quad.uv_layers["UVMap"].active_render = True
    if read_through != "render-active map":  # the UV Map node reached through nodes that change nothing
        tree = obj.active_material.node_tree
        vector = next(n for n in tree.nodes if n.type == "TEX_IMAGE").inputs["Vector"]
        if read_through.endswith("Mapping"):
            mapping = tree.nodes.new("ShaderNodeMapping")
            tree.links.new(mapping.outputs["Vector"], vector)
            vector = mapping.inputs["Vector"]
        if read_through.endswith("group"):
            group = bpy.data.node_groups.new("UVs", "ShaderNodeTree")
            group.interface.new_socket("Vector", in_out="OUTPUT", socket_type="NodeSocketVector")
            holder = tree.nodes.new("ShaderNodeGroup")
            holder.node_tree = group
            tree.links.new(holder.outputs[0], vector)
            tree, vector = group, group.nodes.new("NodeGroupOutput").inputs[0]
        node = tree.nodes.new("ShaderNodeUVMap")
        node.uv_map = "Turned"
        tree.links.new(node.outputs["UV"], vector)
    corners = checks.mesh_points(obj)[:, :2].astype(np.float64)
    maps = {layer.name: np.linalg.lstsq(np.column_stack([corners, np.ones(4)]), uv_of_points(quad, layer.name),
                                        rcond=None)[0] for layer in quad.uv_layers}
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    cutout = obj.data
    points = np.column_stack([checks.mesh_points(obj)[:, :2], np.ones(len(cutout.vertices))])
    for name, affine in maps.items():
        assert name in cutout.uv_layers, f"UV map '{name}' was dropped"
        error = np.abs(uv_of_points(cutout, name) - points @ affine).max()
        assert error < 1e-5, f"UV map '{name}' is {error:.3f} off what the quad showed"
    assert [layer.name for layer in cutout.uv_layers] == ["UVMap", "Turned", "Scratch"]
    assert cutout.uv_layers.active.name == "Scratch" and cutout.uv_layers["UVMap"].active_render
    # Cut out through the map the picture is read by: around its visible pixels, a pixel's margin.
    picture = uv_of_points(cutout, "UVMap" if read_through == "render-active map" else "Turned")
    yy, xx = np.nonzero(pixels[..., 3] > 0)
    two_pixels = 2.0 / np.array([W, H])
    assert np.all(np.abs(picture.min(axis=0) - [xx.min() / W, yy.min() / H]) < two_pixels)
    assert np.all(np.abs(picture.max(axis=0) - [(xx.max() + 1) / W, (yy.max() + 1) / H]) < two_pixels)

    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    picture_map = "UVMap" if read_through == "render-active map" else "Turned"
    obj.data.uv_layers[picture_map].data.foreach_set("uv", np.full(2 * len(quad.loops), 0.5, np.float32))
    with pytest.raises(RuntimeError, match=f"its UV map '{picture_map}', which shows its picture, shows none of it"):
        bpy.ops.shapedeform.bind()


def test_bind_says_when_the_picture_is_read_through_changed_coordinates_or_is_one_of_two(addon, tmp_path,
                                                                                          capsys):
    """A Mapping node that scales the UVs, a second picture with alpha wired to the shader: what
    is cut out may not be what renders, and Bind says so (it cut out silently: a disc vanished,
    or the cut-out missed the scaled picture)."""
    obj, _ = import_picture(tmp_path)
    tree = obj.active_material.node_tree
    image = next(n for n in tree.nodes if n.type == "TEX_IMAGE")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (2.0, 2.0, 1.0)
    tree.links.new(tree.nodes.new("ShaderNodeUVMap").outputs["UV"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], image.inputs["Vector"])
    second = tree.nodes.new("ShaderNodeTexImage")
    second.image = image.image.copy()
    second.image.name = "Line Art"
    math = tree.nodes.new("ShaderNodeMath")
    tree.links.new(second.outputs["Alpha"], math.inputs[0])
    tree.links.new(math.outputs[0], next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED").inputs["Roughness"])
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    said = capsys.readouterr().out
    assert f"'{mapping.name}' changes the coordinates its picture is read through" in said
    assert "is cut out, not 'Line Art'" in said


def test_the_picture_the_face_shows_is_the_one_cut_out(addon, tmp_path):
    """The quad's face shows the material of its second slot (a disc on the right); the first
    slot's material has a disc on the left. Bind cuts out the right disc and the cut-out's faces
    show the same slot (it cut out the left disc, u 3.5 to 25.5 of 64, and showed slot 0)."""
    yy, xx = np.mgrid[:H, :W]
    discs = {}
    for name, centre in (("left", 14), ("right", 50)):
        pixels = np.ones((H, W, 4), np.float32)
        pixels[..., 3] = ((xx - centre) ** 2 + (yy - 24) ** 2) < 10 ** 2
        discs[name] = checks.import_picture(tmp_path, name, pixels)
    obj = discs["left"]
    obj.data.materials.append(discs["right"].active_material)
    obj.data.polygons[0].material_index = 1
    bpy.data.objects.remove(discs["right"])
    checks.select_only(obj)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    u = uv_of_points(obj.data)[:, 0] * W
    assert (u.min(), u.max()) == pytest.approx((50 - 11, 50 + 11), abs=1.0)
    slots = np.empty(len(obj.data.polygons), np.int32)
    obj.data.polygons.foreach_get("material_index", slots)
    assert set(slots) == {1}


def test_a_quad_with_a_corner_moved_shows_the_same_picture_once_cut_out(addon, tmp_path):
    """One corner of the quad moved (no parallelogram): Blender shows the picture over the quad's
    two triangles, each mapped affinely, and so does the cut-out. Measured on Workbench renders
    before and after Bind, by the picture's colours (red grows with x, green with y): the same
    to one level in 255 (one affine map fitted to the four corners put them up to 0.34 off, 0.09
    at the 99th percentile), and on the cut-out's UVs (they were up to 0.048 of the picture off)."""
    import renders

    obj, _ = import_picture(tmp_path)
    quad = obj.data
    quad.vertices[3].co += Vector((0.3, 0.2, 0.0))
    corners = checks.mesh_points(obj)[:, :2].astype(np.float64)
    corner_uv = uv_of_points(quad)
    quad.calc_loop_triangles()
    halves = [corners[list(t.vertices)] for t in quad.loop_triangles]
    halves_uv = [corner_uv[list(t.vertices)] for t in quad.loop_triangles]
    renders.camera_over((0.15, 0.1), 1.8)
    before = renders.render(tmp_path / "before.png", color_type="TEXTURE")
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    after = renders.render(tmp_path / "after.png", color_type="TEXTURE")

    # Pixels inside the picture on both renders (not on its edge): the same colours.
    lit = (before[..., :3].max(axis=2) > 0.05) & (after[..., :3].max(axis=2) > 0.05)
    inner = lit & np.roll(lit, 1, 0) & np.roll(lit, -1, 0) & np.roll(lit, 1, 1) & np.roll(lit, -1, 1)
    assert inner.sum() > 2000
    difference = np.abs(after[inner, :2] - before[inner, :2])
    assert difference.max() <= 2.0 / 255.0, f"colours differ by up to {difference.max():.3f}"
    points = checks.mesh_points(obj)[:, :2].astype(np.float64)
    shown = np.full((len(points), 2), np.nan)
    for (a, b, c), (ua, ub, uc) in zip(halves, halves_uv):  # the quad's UV at each point, by its triangle
        weights = np.linalg.solve(np.array([b - a, c - a]).T, (points - a).T).T
        inside = (weights >= -1e-6).all(axis=1) & (weights.sum(axis=1) <= 1 + 1e-6)
        shown[inside] = (ua + weights @ np.array([ub - ua, uc - ua]))[inside]
    on_quad = np.isfinite(shown).all(axis=1)
    assert on_quad.sum() > 0.9 * len(points)
    error = np.abs(uv_of_points(obj.data)[on_quad] - shown[on_quad]).max()
    assert error < 1e-5, f"the cut-out's UVs are up to {error:.3f} of the picture off the quad's"


@pytest.mark.parametrize("edit, said", [("none", None), ("uv", "UV maps ('UVMap'"),
                                        ("colour", "attributes added to its cut-out ('Paint'"),
                                        ("weights", "vertex-group weights"),
                                        ("uv renamed", "UV maps renamed on its cut-out ('UVMap' as 'Renamed'"),
                                        ("uv added", "UV maps added to its cut-out ('Extra'"),
                                        ("uv deleted", "UV maps deleted from its cut-out ('UVMap'")])
def test_unbind_names_the_uv_colour_and_weight_edits_it_drops(addon, tmp_path, edit, said):
    """UVs edited, a colour attribute painted, vertex-group weights given or UV maps renamed,
    added or deleted on the cut-out go with it on Unbind, which says so by name (it said
    nothing; a UV map renamed or added was called an attribute added, "colours and the like";
    one deleted went unsaid); a trip through Edit Mode that edits nothing is no edit."""
    import bmesh

    obj, _ = import_picture(tmp_path)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    cutout = obj.data
    bpy.ops.object.mode_set(mode="EDIT")
    if edit == "uv":
        edited = bmesh.from_edit_mesh(cutout)
        layer = edited.loops.layers.uv.active
        for loop in next(iter(edited.faces)).loops:
            loop[layer].uv *= 0.5
        bmesh.update_edit_mesh(cutout)
    bpy.ops.object.mode_set(mode="OBJECT")
    if edit == "colour":
        paint = cutout.color_attributes.new("Paint", "FLOAT_COLOR", "POINT")
        paint.data.foreach_set("color", np.tile(np.float32([1, 0, 0, 1]), len(cutout.vertices)))
    elif edit == "weights":
        obj.vertex_groups.new(name="Arm").add(list(range(10)), 1.0, "REPLACE")
    elif edit == "uv renamed":
        cutout.uv_layers["UVMap"].name = "Renamed"
    elif edit == "uv added":
        cutout.uv_layers.new(name="Extra")
    elif edit == "uv deleted":
        cutout.uv_layers.remove(cutout.uv_layers["UVMap"])
    lost = addon.shapedeform_addon.binding.unbind(obj)
    assert len(obj.data.vertices) == 4
    if said is None:
        assert lost == []
    else:
        assert len(lost) == 1 and said in lost[0], lost


def test_bind_says_a_quads_shape_keys_stop_showing(addon, tmp_path, capsys):
    """A quad squashed by a shape key (height 0.5 of 1) shows unsquashed once cut out (0.667:
    the cut-out has no keys): Bind says so (it said nothing), and Unbind gives the keys back."""
    obj, _ = import_picture(tmp_path)
    obj.shape_key_add(name="Basis")
    squash = obj.shape_key_add(name="Squash")
    squash.data.foreach_set("co", (checks.mesh_points(obj) * [1.0, 0.5, 1.0]).astype(np.float32).ravel())
    squash.value = 1.0
    bpy.context.view_layer.update()
    squashed = np.ptp(checks.evaluated_mesh_points(obj)[:, 1])
    assert squashed == pytest.approx(0.5)
    capsys.readouterr()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert "its shape keys stop showing while it is bound" in capsys.readouterr().out
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    bpy.context.view_layer.update()
    assert np.ptp(checks.evaluated_mesh_points(obj)[:, 1]) == pytest.approx(squashed)


def test_a_copy_whose_cut_out_takes_a_name_the_quad_still_lists_gets_a_quad_of_its_own(addon, tmp_path, quiet):
    """Two planes bound on one quad, the second deleted while bound, the file saved, reopened
    and cleaned up (its cut-out goes): a Shift+D copy of the first has a cut-out of that freed
    name, which the quad still listed, so the copy kept the first's quad, and scaling the
    copy's mesh after Unbind scaled the first's picture too (corners 1.333 for 0.667)."""
    first, _ = import_picture(tmp_path)
    quad_points = checks.mesh_points(first).copy()
    second = duplicate(first, linked=True)
    second.location.x += 2.5
    bind(first)
    bind(second)
    handles = second.shapedeform.handle_collection
    checks.select_only(second)
    assert bpy.ops.object.delete() == {"FINISHED"}
    for empty in list(handles.all_objects):
        bpy.data.objects.remove(empty)
    bpy.data.collections.remove(handles)
    path, name = str(tmp_path / "deleted.blend"), first.name
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    bpy.data.orphans_purge(do_local_ids=True, do_linked_ids=True, do_recursive=True)
    first = bpy.data.objects[name]
    copy = duplicate(first, linked=False)
    assert copy.shapedeform.original_data != first.shapedeform.original_data
    unbind(first)  # releases the copy
    copy.data.transform(Matrix.Scale(2.0, 4))
    np.testing.assert_array_equal(checks.mesh_points(first), quad_points)


@pytest.mark.parametrize("wiring", ["unwired", "muted", "into a shader left out", "inverted"])
def test_a_plane_whose_material_does_not_show_its_alpha_is_rigged_as_it_renders(addon, tmp_path, capsys, wiring):
    """The picture's Alpha unwired, its link muted, or into a shader the material's output does
    not show, the plane renders whole: it is rigged whole and renders the same after Bind (it
    was cut to the alpha: 1,536 lit pixels became 473). Read through an Invert node, what is cut
    out may not be what renders: Bind says so (it said nothing)."""
    import renders

    obj, _ = import_picture(tmp_path)
    tree = obj.active_material.node_tree
    image = next(n for n in tree.nodes if n.type == "TEX_IMAGE")
    shader = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    if wiring == "muted":
        image.outputs["Alpha"].links[0].is_muted = True
    elif wiring == "into a shader left out":
        emission = tree.nodes.new("ShaderNodeEmission")
        tree.links.new(image.outputs["Color"], emission.inputs["Color"])
        output = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
        tree.links.new(emission.outputs[0], output.inputs["Surface"])
    else:
        tree.links.remove(image.outputs["Alpha"].links[0])
    if wiring == "inverted":
        invert = tree.nodes.new("ShaderNodeInvert")
        tree.links.new(image.outputs["Alpha"], invert.inputs["Color"])
        tree.links.new(invert.outputs["Color"], shader.inputs["Alpha"])
    quad = checks.mesh_points(obj)
    renders.camera_over((0.0, 0.0), 1.6)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))  # lights the plane's shader
    bpy.context.scene.collection.objects.link(sun)
    before = renders.render(tmp_path / "before.png", engine="CYCLES", size=40, samples=4)
    capsys.readouterr()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    said = capsys.readouterr().out
    if wiring == "inverted":
        assert f"'{invert.name}' changes its picture's alpha on the way to the shader" in said
        return
    assert "nothing reads the alpha of its picture 'picture.png', so the whole plane is rigged" in said
    lit = lambda pixels: pixels[..., :3].max(axis=2) > 0.05
    after = renders.render(tmp_path / "after.png", engine="CYCLES", size=40, samples=4)
    assert lit(before).sum() > 200 and (lit(after) == lit(before)).all()
    lo, hi = quad.min(axis=0), quad.max(axis=0)
    assert checks.area(obj, checks.mesh_points(obj)) == pytest.approx(np.prod((hi - lo)[:2]), rel=1e-6)


def test_bind_says_how_many_specks_of_the_picture_it_leaves_out(addon, tmp_path, capsys):
    """A lone pixel at 90% opacity holds less ink than one opaque pixel: the cut-out leaves it
    out as a speck, and Bind says so (it dropped it without a word)."""
    yy, xx = np.mgrid[:H, :W]
    pixels = np.ones((H, W, 4), np.float32)
    pixels[..., 3] = ((xx - 40) ** 2 + (yy - 22) ** 2) < 15 ** 2
    pixels[5, 5, 3] = 0.9
    checks.import_picture(tmp_path, "speck", pixels)
    capsys.readouterr()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert "1 speck of its picture with less ink than one opaque pixel (the most opaque 90%) is left out" \
        in capsys.readouterr().out


def test_a_second_node_of_the_same_picture_is_not_told_as_another_picture(addon, tmp_path, capsys):
    """Importing a picture again, Blender 5's importer reuses its material and adds a second
    Image Texture node of the same picture: Bind said "only the picture 'picture.png' is cut
    out, not 'picture.png'" (and the demo printed it)."""
    obj, _ = import_picture(tmp_path)
    tree = obj.active_material.node_tree
    image = next(n for n in tree.nodes if n.type == "TEX_IMAGE")
    for _ in range(2):
        again = tree.nodes.new("ShaderNodeTexImage")
        again.image = image.image
        tree.links.new(again.outputs["Alpha"], tree.nodes.new("ShaderNodeMath").inputs[0])
    capsys.readouterr()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert "is cut out, not" not in capsys.readouterr().out


@pytest.mark.parametrize("depth", [1, 2])
def test_a_picture_read_inside_a_node_group_is_cut_out(addon, tmp_path, capsys, depth):
    """A material built of node groups (a sprite group holding the Image Texture, fed its UVs
    from outside, its Color and Alpha out to the shader): Bind cut nothing out and rigged the
    whole quad without a word. The picture is now cut out through the UV map fed in from
    outside the groups, as in the material's own tree."""
    obj, pixels = import_picture(tmp_path)
    quad = obj.data
    imported = uv_of_points(quad)
    loops = np.empty(len(quad.loops), np.int32)
    quad.loops.foreach_get("vertex_index", loops)
    turned = np.stack([1.0 - imported[:, 1], imported[:, 0]], axis=1)
    quad.uv_layers.new(name="Turned").data.foreach_set("uv", turned[loops].astype(np.float32).ravel())
    tree = obj.active_material.node_tree
    image = next(n for n in tree.nodes if n.type == "TEX_IMAGE")
    shader = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    uv_map = tree.nodes.new("ShaderNodeUVMap")
    uv_map.uv_map = "Turned"
    outer, vector, color, alpha = tree, uv_map.outputs["UV"], shader.inputs["Base Color"], shader.inputs["Alpha"]
    for level in range(depth):  # each level a group node whose Vector in and Color, Alpha out are wired through
        group = bpy.data.node_groups.new(f"Sprite {level}", "ShaderNodeTree")
        group.interface.new_socket("Vector", in_out="INPUT", socket_type="NodeSocketVector")
        group.interface.new_socket("Color", in_out="OUTPUT", socket_type="NodeSocketColor")
        group.interface.new_socket("Alpha", in_out="OUTPUT", socket_type="NodeSocketFloat")
        holder = outer.nodes.new("ShaderNodeGroup")
        holder.node_tree = group
        outer.links.new(vector, holder.inputs["Vector"])
        outer.links.new(holder.outputs["Color"], color)
        outer.links.new(holder.outputs["Alpha"], alpha)
        inputs, outputs = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
        outer, vector, color, alpha = group, inputs.outputs["Vector"], outputs.inputs["Color"], outputs.inputs["Alpha"]
    inner = outer.nodes.new("ShaderNodeTexImage")
    inner.image, inner.interpolation = image.image, image.interpolation
    outer.links.new(vector, inner.inputs["Vector"])
    outer.links.new(inner.outputs["Color"], color)
    outer.links.new(inner.outputs["Alpha"], alpha)
    tree.nodes.remove(image)
    capsys.readouterr()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    said = capsys.readouterr().out
    assert obj.shapedeform.kind == "IMAGE" and len(obj.data.vertices) > 4
    assert "changes" not in said and "nothing reads" not in said, said
    picture = uv_of_points(obj.data, "Turned")  # cut out around the visible pixels, within two pixels
    yy, xx = np.nonzero(pixels[..., 3] > 0)
    two_pixels = 2.0 / np.array([W, H])
    assert np.all(np.abs(picture.min(axis=0) - [xx.min() / W, yy.min() / H]) < two_pixels)
    assert np.all(np.abs(picture.max(axis=0) - [(xx.max() + 1) / W, (yy.max() + 1) / H]) < two_pixels)


def sprite_group(image, inputs=("Vector",), outputs=("Color", "Alpha"), dead_shader=False):
    """A node group holding an Image Texture of ``image``: its Vector from the group's input,
    its Color and Alpha out (or its Alpha into a Principled BSDF wired to nothing)."""
    group = bpy.data.node_groups.new("Sprite", "ShaderNodeTree")
    for name in inputs:
        group.interface.new_socket(name, in_out="INPUT", socket_type="NodeSocketVector")
    for name in outputs:
        group.interface.new_socket(name, in_out="OUTPUT", socket_type="NodeSocketColor" if name == "Color"
                                   else "NodeSocketFloat")
    given, out, texture = (group.nodes.new(kind) for kind in ("NodeGroupInput", "NodeGroupOutput", "ShaderNodeTexImage"))
    texture.image = image
    if inputs:
        group.links.new(given.outputs["Vector"], texture.inputs["Vector"])
    for name in outputs:
        group.links.new(texture.outputs[name], out.inputs[name])
    if dead_shader:
        group.links.new(texture.outputs["Alpha"], group.nodes.new("ShaderNodeBsdfPrincipled").inputs["Alpha"])
    return group


def picture_in_group(obj, **options):
    """Replace the plane's Image Texture by a group node of :func:`sprite_group`; (tree, shader, group node)."""
    tree = obj.active_material.node_tree
    image = next(n for n in tree.nodes if n.type == "TEX_IMAGE")
    shader = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    holder = tree.nodes.new("ShaderNodeGroup")
    holder.node_tree = sprite_group(image.image, **options)
    tree.nodes.remove(image)
    return tree, shader, holder


def muted_picture(obj):
    next(n for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE").mute = True


def muted_group(obj):
    tree, shader, holder = picture_in_group(obj)
    tree.links.new(holder.outputs["Color"], shader.inputs["Base Color"])
    tree.links.new(holder.outputs["Alpha"], shader.inputs["Alpha"])
    holder.mute = True


def dead_shader_in_group(obj):
    tree, shader, holder = picture_in_group(obj, outputs=("Color",), dead_shader=True)
    tree.links.new(holder.outputs["Color"], shader.inputs["Base Color"])


def sphere_projection(obj):
    next(n for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE").projection = "SPHERE"


def unlinked_group_vector(obj):
    tree, shader, holder = picture_in_group(obj)
    tree.links.new(holder.outputs["Color"], shader.inputs["Base Color"])
    tree.links.new(holder.outputs["Alpha"], shader.inputs["Alpha"])


def group_used_twice(obj):
    tree, shader, first = picture_in_group(obj)
    second = tree.nodes.new("ShaderNodeGroup")
    second.node_tree = first.node_tree
    uv_map = tree.nodes.new("ShaderNodeUVMap")
    for holder in (first, second):
        tree.links.new(uv_map.outputs["UV"], holder.inputs["Vector"])
    tree.links.new(first.outputs["Color"], shader.inputs["Base Color"])
    tree.links.new(second.outputs["Alpha"], shader.inputs["Alpha"])


def read_again_through_another_map(obj):
    quad = obj.data
    uv = np.empty(2 * len(quad.loops), np.float32)
    quad.uv_layers[0].data.foreach_get("uv", uv)
    quad.uv_layers.new(name="Shifted").data.foreach_set("uv", (uv.reshape(-1, 2) + [0.4, 0.0]).ravel())
    tree = obj.active_material.node_tree
    first = next(n for n in tree.nodes if n.type == "TEX_IMAGE")
    second = tree.nodes.new("ShaderNodeTexImage")
    second.image = first.image
    uv_map = tree.nodes.new("ShaderNodeUVMap")
    uv_map.uv_map = "Shifted"
    tree.links.new(uv_map.outputs["UV"], second.inputs["Vector"])
    shader = tree.nodes.new("ShaderNodeBsdfPrincipled")
    tree.links.new(second.outputs["Alpha"], shader.inputs["Alpha"])
    mix = tree.nodes.new("ShaderNodeMixShader")
    output = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    tree.links.new(output.inputs["Surface"].links[0].from_socket, mix.inputs[1])
    tree.links.new(shader.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], output.inputs["Surface"])


def on_a_second_tile(obj):
    image = next(n for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE").image
    image.source = "TILED"
    quad = obj.data
    uv = np.empty(2 * len(quad.loops), np.float32)
    quad.uv_layers[0].data.foreach_get("uv", uv)
    quad.uv_layers[0].data.foreach_set("uv", (uv.reshape(-1, 2) + [1.0, 0.0]).ravel())


# How the material reads the picture, whether the plane renders whole (then it is rigged
# whole), and what Bind says. From a QA round: each of these was cut to the picture, silently,
# where it renders otherwise (up to 72% of the visible pixels lost), or the reverse.
READINGS = {
    "picture muted": (muted_picture, True, "nothing reads the alpha"),
    "group muted": (muted_group, True, "nothing reads the alpha"),
    "a shader left out in the group reads it": (dead_shader_in_group, True, "nothing reads the alpha"),
    "sphere projection": (sphere_projection, False, "changes the coordinates its picture is read through"),
    "group's Vector unlinked": (unlinked_group_vector, False, "changes the coordinates its picture is read through"),
    "group used twice, colour and alpha": (group_used_twice, False, ""),
    "read again through another UV map": (read_again_through_another_map, False,
                                          "its picture is also read through other coordinates"),
    "UDIM tile 1002": (on_a_second_tile, True, "tiled (UDIM) picture shown on a tile other than 1001"),
}


@pytest.mark.parametrize("reading", READINGS)
def test_bind_cuts_out_the_picture_as_the_material_reads_it_or_says_why_not(addon, tmp_path, capsys, reading):
    obj, _ = import_picture(tmp_path)
    setup, whole, said = READINGS[reading]
    setup(obj)
    capsys.readouterr()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    out = capsys.readouterr().out
    points = checks.mesh_points(obj)
    box = np.prod((points.max(axis=0) - points.min(axis=0))[:2])
    if whole:
        assert checks.area(obj, points) == pytest.approx(box, rel=1e-6)
    else:
        assert checks.area(obj, points) < 0.8 * box  # cut out
    if said:
        assert said in out, out
    else:
        assert "nothing reads" not in out and "changes" not in out, out


def test_a_float_picture_with_nan_in_its_alpha_binds(addon, tmp_path):
    """One NaN in an EXR's alpha (a render's firefly) stopped Bind with a Python traceback (QA)."""
    obj, pixels = import_picture(tmp_path)
    image = next(n for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE").image
    flat = np.array(pixels, np.float32)
    flat[5, 5, 3] = np.nan
    floating = bpy.data.images.new("floating", W, H, alpha=True, float_buffer=True)
    floating.pixels.foreach_set(flat.ravel())
    next(n for n in obj.active_material.node_tree.nodes if n.type == "TEX_IMAGE").image = floating
    assert image != floating
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert np.all(np.isfinite(checks.mesh_points(obj))) and len(obj.data.vertices) > 4
