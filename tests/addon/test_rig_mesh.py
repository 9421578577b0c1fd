# SPDX-License-Identifier: GPL-3.0-or-later
"""Rigging planar meshes: bind, handles, live posing, save and reopen, unbind exactly."""

import bmesh
import bpy
import numpy as np
import pytest
from mathutils import Matrix, Vector
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

import rig_checks as checks


def grid(name="Grid", x=12, y=6, turn=None):
    """A 2 x 1 grid of quads, turned to an arbitrary plane when ``turn`` is given."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=x, y_subdivisions=y, size=1.0)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.transform(Matrix.Diagonal((2.0, 1.0, 1.0, 1.0)))
    if turn is not None:
        obj.data.transform(turn)
    obj.location = (0.5, -1.0, 0.25)
    bpy.context.view_layer.update()
    return obj


def rig_with_two_handles():
    """A bound grid with a handle near each end: (object, left handle, right handle)."""
    obj = grid()
    left, right = checks.bind_with_handles(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    return obj, left, right


TILTED = Matrix.Rotation(0.7, 4, Vector((1.0, 2.0, 0.5)).normalized())


@pytest.mark.parametrize("mode", ["OWN", "OUTLINE"])
def test_mesh_follows_handles_in_any_plane(addon, mode):
    obj = grid(turn=TILTED)
    rest = checks.mesh_points(obj)
    obj.shapedeform.graph_mode = mode
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert obj.shapedeform.is_bound
    left, right = checks.world(obj, rest[np.argmin(rest @ TILTED.to_3x3().col[0])]), \
        checks.world(obj, rest[np.argmax(rest @ TILTED.to_3x3().col[0])])
    a = checks.add_handle(obj, left)
    b = checks.add_handle(obj, right)
    # Adding handles never moves the shape.
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), rest, atol=1e-5)
    assert [item.object for item in obj.shapedeform.handles] == [a, b]
    assert a.users_collection[0] == obj.shapedeform.handle_collection

    plane_normal = TILTED.to_3x3() @ Vector((0, 0, 1))
    in_plane = TILTED.to_3x3() @ Vector((0, 1, 0))
    b.matrix_world.translation = Vector(right) + 0.6 * in_plane
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(obj)
    checks.assert_posed(obj, rest, posed, reached=[(right, b)], exact=mode == "OWN",
                        normal=np.array(plane_normal))
    assert obj.shapedeform.status == ""


def test_binding_rebuilds_an_older_node_group_and_its_rigs_keep_working(addon):
    # A file made by an older extension has an older "Shape Deform" group; binding in it
    # rebuilds that shared group in place, and the modifiers already using it keep their cage.
    nodes = addon.shapedeform_addon.nodes
    obj, _, right = rig_with_two_handles()
    right.location.y += 0.4
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(obj)
    group = obj.modifiers["Shape Deform"].node_group
    group[nodes.VERSION_KEY] = nodes.VERSION - 1
    other = grid("Other")
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert other.modifiers["Shape Deform"].node_group == group
    assert group[nodes.VERSION_KEY] == nodes.VERSION
    bpy.context.view_layer.update()
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), posed, atol=1e-6)
    right.location.y -= 0.4
    bpy.context.view_layer.update()
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), checks.mesh_points(obj), atol=1e-5)


def test_rotating_a_handle_turns_its_region_and_area_is_kept(addon):
    obj = grid(x=16, y=8)
    rest = checks.mesh_points(obj)
    obj.shapedeform.preserve_area = True
    bpy.ops.shapedeform.bind()
    checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    b = checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    before = checks.evaluated_mesh_points(obj)
    b.rotation_euler.z += 0.6
    b.location.y += 0.5
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(obj)
    checks.assert_posed(obj, rest, posed, normal=np.array([0, 0, 1.0]))
    # The region b owns (the mesh is its own graph: graph points are vertices) turned with it.
    i, j = np.asarray(obj.shapedeform.handles[1]["indices"])[:2]
    turned = np.arctan2(*(posed[j, :2] - posed[i, :2])[::-1]) - np.arctan2(*(before[j, :2] - before[i, :2])[::-1])
    turned = np.angle(np.exp(1j * turned))  # a pair along -x sits at +-pi: compare turns modulo 2 pi
    assert turned == pytest.approx(0.6, abs=1e-4)
    assert checks.area(obj, posed) == pytest.approx(checks.area(obj, rest), rel=1e-3)


def test_save_reopen_keeps_the_rig_working_and_unbind_is_exact(addon, tmp_path):
    obj = grid()
    rest = checks.mesh_points(obj).copy()
    bpy.ops.shapedeform.bind()
    checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    handle = checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    handle.location.y += 0.3
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(obj).copy()
    path = str(tmp_path / "rig.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    bpy.ops.wm.open_mainfile(filepath=path)  # runs load_post
    obj = bpy.data.objects["Grid"]
    assert checks.mesh_points(obj).tobytes() == rest.tobytes()  # the mesh is never the pose
    np.testing.assert_array_equal(checks.evaluated_mesh_points(obj), posed)
    handle = obj.shapedeform.handles[1].object
    handle.location.y += 0.2
    bpy.context.view_layer.update()
    moved = checks.evaluated_mesh_points(obj)
    assert np.abs(moved - posed).max() > 0.1
    checks.assert_posed(obj, rest, moved, normal=np.array([0, 0, 1.0]))

    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert checks.mesh_points(obj).tobytes() == rest.tobytes()
    assert "sd_rest" not in obj.data.attributes
    assert not obj.shapedeform.is_bound and len(obj.shapedeform.handles) == 0
    assert [o.name for o in bpy.data.objects] == ["Grid"]
    assert not any("Handles" in c.name for c in bpy.data.collections)
    assert "graph_points" not in obj.shapedeform


def test_frame_change_poses_animated_handles(addon):
    obj, _, handle = rig_with_two_handles()
    scene = bpy.context.scene
    start = handle.location.copy()
    handle.keyframe_insert("location", frame=1)
    handle.location.y += 0.4
    handle.keyframe_insert("location", frame=10)
    tip = np.argmin(np.linalg.norm(checks.mesh_points(obj)[:, :2] - [1.0, 0.0], axis=1))
    scene.frame_set(10)
    at_ten = checks.evaluated_mesh_points(obj)
    assert at_ten[tip, 1] == pytest.approx(0.4, abs=1e-5)  # not a frame late
    scene.frame_set(5)
    assert checks.evaluated_mesh_points(obj)[tip, 1] == pytest.approx(handle.location.y - start.y, abs=1e-5)
    scene.frame_set(1)
    assert checks.evaluated_mesh_points(obj)[tip, 1] == pytest.approx(0.0, abs=1e-5)


def test_remove_handle_and_text_mesh_with_holes(addon):
    bpy.ops.object.text_add()
    bpy.context.object.data.body = "Bo"
    bpy.ops.object.convert(target="MESH")
    obj = bpy.context.active_object
    rest = checks.mesh_points(obj)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    # "B" is the left letter; handles on its left and right edges.
    left = rest[np.argmin(rest[:, 0])]
    a = checks.add_handle(obj, checks.world(obj, left))
    b_points = rest[rest[:, 0] < lo[0] + 0.45 * (hi[0] - lo[0])]
    b = checks.add_handle(obj, checks.world(obj, b_points[np.argmax(b_points[:, 0])]))
    b.location.y += 0.2
    bpy.context.view_layer.update()
    posed = checks.evaluated_mesh_points(obj)
    checks.assert_posed(obj, rest, posed, normal=np.array([0, 0, 1.0]))
    for o in bpy.context.selected_objects:
        o.select_set(False)
    b.select_set(True)
    assert bpy.ops.shapedeform.remove_handle() == {"FINISHED"}
    assert [i.object for i in obj.shapedeform.handles] == [a]
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), rest, atol=1e-5)


def test_add_handles_at_selected_vertices(addon):
    obj = grid()
    bpy.ops.shapedeform.bind()
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="DESELECT")
    bpy.ops.object.mode_set(mode="OBJECT")
    for i in (0, 5):
        obj.data.vertices[i].select = True
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    handles = [i.object for i in obj.shapedeform.handles]
    assert len(handles) == 2
    expected = [checks.world(obj, obj.data.vertices[i].co) for i in (0, 5)]
    np.testing.assert_allclose([h.matrix_world.translation for h in handles], expected, atol=1e-6)


@pytest.mark.parametrize("make, message", [
    (lambda: bpy.data.meshes.new("Empty"), "no vertices"),
    ("cube", "not planar"),
    ("camera", "is a camera object"),
    ("empty", "is an empty object"),  # issue 15, defect 13: not "a empty"
    ("armature", "is an armature object"),
])
def test_bad_input_is_refused_and_changes_nothing(addon, make, message):
    if make == "cube":
        bpy.ops.mesh.primitive_cube_add()
    elif make == "camera":
        bpy.ops.object.camera_add()
    elif make == "empty":
        bpy.ops.object.empty_add()
    elif make == "armature":
        bpy.ops.object.armature_add()
    else:
        obj = bpy.data.objects.new("Empty mesh", make())
        bpy.context.scene.collection.objects.link(obj)
        bpy.context.view_layer.objects.active = obj
    obj = bpy.context.active_object
    before = checks.snapshot()
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.shapedeform.bind()
    assert not obj.shapedeform.is_bound
    assert checks.snapshot() == before


def _flipped_area_fraction(obj, rest_areas):
    """Share of the evaluated mesh's area whose triangles turned over against ``rest_areas``."""
    areas = _evaluated_signed_areas(obj)
    flipped = np.sign(areas) != np.sign(rest_areas)
    return float(np.abs(rest_areas[flipped]).sum() / np.abs(rest_areas).sum())


def _evaluated_signed_areas(obj):
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    mesh.calc_loop_triangles()
    points = checks.mesh_points(obj, mesh)[:, :2]
    tris = np.array([t.vertices[:] for t in mesh.loop_triangles])
    evaluated.to_mesh_clear()
    return checks.signed_areas(points, tris)


def test_a_mesh_whose_faces_share_no_vertices_deforms_as_one_piece(addon):
    """As an OBJ import or Edge Split leaves a mesh: every face with vertices of its own. It
    moves as the same mesh welded does (each face was an island of its own graph, and the
    middle of the strip did not move at all), and its data is left as it is."""
    welded = grid("Welded")
    unwelded = grid("Unwelded")
    mesh = unwelded.data
    bpy.context.view_layer.objects.active = unwelded
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.mesh.edge_split(type="EDGE")
    bpy.ops.object.mode_set(mode="OBJECT")
    assert len(mesh.vertices) == 4 * len(mesh.polygons)
    before = checks.mesh_points(unwelded).copy()
    poses = []
    for obj in (welded, unwelded):
        _, end = checks.bind_with_handles(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0])
        end.location.y += 0.5
        bpy.context.view_layer.update()
        assert obj.shapedeform.status == ""
        poses.append(checks.evaluated_mesh_points(obj))
    # Each vertex of the split mesh moves as the welded mesh's vertex at its place.
    same_place = np.linalg.norm(before[:, None] - checks.mesh_points(welded)[None], axis=2).argmin(axis=1)
    np.testing.assert_allclose(poses[1], poses[0][same_place], atol=1e-4)
    np.testing.assert_array_equal(checks.mesh_points(unwelded), before)


@pytest.mark.parametrize("loose, message", [(1, "1 vertex is on no face"), (2, "2 vertices are on no face")])
def test_graph_mesh_refuses_vertices_on_no_face_and_says_how_many(addon, loose, message):
    """Graph: Mesh on a grid with loose vertices beside it names them in agreement with their
    count ("1 vertices are on no face" was said of one) and changes nothing."""
    obj = grid()
    obj.data.vertices.add(loose)
    for i, vertex in enumerate(obj.data.vertices[-loose:]):
        vertex.co = (1.5, 0.1 * i, 0.0)
    obj.data.update()
    obj.shapedeform.graph_mode = "OWN"
    before = checks.snapshot()
    with pytest.raises(RuntimeError, match=f"{message}; use the Outline graph"):
        bpy.ops.shapedeform.bind()
    assert checks.snapshot() == before


def quads(nx, ny, width, height, x0, y0, start):
    """A grid of nx x ny quads, width x height from (x0, y0), its vertices numbered from ``start``."""
    verts = [(x0 + width * i / nx, y0 + height * j / ny, 0.0) for j in range(ny + 1) for i in range(nx + 1)]
    faces = [[start + j * (nx + 1) + i + k for k in (0, 1, nx + 2, nx + 1)] for j in range(ny) for i in range(nx)]
    return verts, faces


def puppet(detail=1):
    """A cut-out puppet modelled as one mesh: a body island (2 x 1) and an arm island lying over
    it to x = 3, some of its vertices on the body's, each ``detail`` times as many quads across.
    Returns (object, the body's vertex count)."""
    body, body_faces = quads(8 * detail, 4 * detail, 2.0, 1.0, 0.0, 0.0, 0)
    arm, arm_faces = quads(6 * detail, 2 * detail, 1.8, 0.4, 1.2, 0.3, len(body))
    mesh = bpy.data.meshes.new("Puppet")
    mesh.from_pydata(body + arm, [], body_faces + arm_faces)
    obj = bpy.data.objects.new("Puppet", mesh)
    bpy.context.scene.collection.objects.link(obj)
    checks.select_only(obj)
    return obj, len(body)


def pose_puppet(obj):
    """Bind the puppet, a handle on the body and one on the hand, the hand dragged up 1.0."""
    checks.select_only(obj)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, (0.0, 0.5, 0.0))
    hand = checks.add_handle(obj, (3.0, 0.5, 0.0))
    hand.location.y += 1.0
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""


def join_into(active, *others):
    """Ctrl+J of ``others`` into ``active``, as the viewport does it (``active`` active, all
    selected), evaluated."""
    checks.select_only(active)
    for other in others:
        other.select_set(True)
    assert bpy.ops.object.join() == {"FINISHED"}
    bpy.context.view_layer.update()


def assert_arm_up_body_still(shown, rest, is_arm):
    """The arm's points moved up 1.0 with the hand, the body's stayed (in the plane: the arm
    also lifts in front)."""
    moved = (shown - rest)[:, :2]
    np.testing.assert_allclose(moved[~is_arm], 0.0, atol=1e-4)
    np.testing.assert_allclose(moved[is_arm], np.tile([0.0, 1.0], (int(is_arm.sum()), 1)), atol=1e-4)


def quad_puppet():
    """A low-poly puppet, bound: a body quad (1 x 2) and an arm quad over it (2.2 x 0.3), one mesh."""
    verts = [(-0.5, -1, 0), (0.5, -1, 0), (0.5, 1, 0), (-0.5, 1, 0), (0.3, 0.4, 0), (2.5, 0.4, 0), (2.5, 0.7, 0),
             (0.3, 0.7, 0)]
    mesh = bpy.data.meshes.new("Puppet")
    mesh.from_pydata(verts, [], [(0, 1, 2, 3), (4, 5, 6, 7)])
    obj = bpy.data.objects.new("Puppet", mesh)
    bpy.context.scene.collection.objects.link(obj)
    checks.select_only(obj)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    return obj


def test_a_low_poly_puppet_gets_a_graph_for_each_part(addon, quiet):
    """A body quad and an arm quad over it, one mesh: Bind made the mesh its own graph (its
    islands overlap), four points a part, so the arm took one handle and refused a second, with
    advice (a higher Graph Density) that did not help. Each island now gets an outline graph of
    its own, kept apart: the arm bends about a shoulder handle while the body stays put."""
    obj = quad_puppet()
    assert len(obj.shapedeform.cage.data.vertices) > 200
    checks.add_handle(obj, (0.0, -0.9, 0.0))
    checks.add_handle(obj, (0.6, 0.55, 0.0))  # the shoulder, off the body
    hand = checks.add_handle(obj, (2.4, 0.55, 0.0))
    hand.location.y += 0.8
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    rest, shown = checks.mesh_points(obj), checks.evaluated_mesh_points(obj)
    moved = np.linalg.norm((shown - rest)[:, :2], axis=1)
    np.testing.assert_allclose(moved[:4], 0.0, atol=1e-4)  # the body, under the arm's root too
    assert moved[5:7].min() > 0.5 and moved[4] < 0.3


def test_an_overlap_pin_that_reaches_no_vertex_of_a_low_poly_mesh_says_so(addon, capsys):
    """A pin lifts the mesh's own vertices: on the middle of a quad arm, beyond the reach of all
    its corners, it changed nothing and said nothing (QA). It now says so and how to mend it;
    once the modifier's Refine cuts the faces, the same pin lifts the arm and says nothing."""
    shape_deform = addon.shapedeform_addon
    obj = quad_puppet()
    capsys.readouterr()
    assert bpy.ops.shapedeform.add_handle(location=(1.4, 0.55, 0.0), kind="OVERLAP") == {"FINISHED"}
    assert "the overlap pin reaches none of 'Puppet''s vertices" in capsys.readouterr().out
    bpy.context.view_layer.update()
    assert np.abs(checks.evaluated_vertices(obj)[:, 2]).max() < 1e-6  # nothing lifted

    modifier = shape_deform.rig_format.modifiers_of(obj)[0]
    subdivision = obj.modifiers.new("Subdivision", "SUBSURF")  # cuts the faces before the rig
    subdivision.subdivision_type, subdivision.levels = "SIMPLE", 3
    checks.select_only(obj)
    assert bpy.ops.object.modifier_move_to_index(modifier=subdivision.name, index=0) == {"FINISHED"}
    bpy.context.view_layer.update()
    assert checks.evaluated_vertices(obj)[:, 2].max() > 1e-3  # the first pin lifts the subdivided arm
    checks.select_only(obj)
    assert bpy.ops.shapedeform.add_handle(location=(1.4, 0.55, 0.0), kind="OVERLAP") == {"FINISHED"}
    assert "reaches none" not in capsys.readouterr().out  # (review: it said so, wrongly)

    obj.modifiers.remove(subdivision)
    refine = shape_deform.nodes.input_identifiers(modifier.node_group)[shape_deform.nodes.REFINE_INPUT]
    shape_deform.compat.set_modifier_input(modifier, refine, 3)
    obj.update_tag()
    bpy.context.view_layer.update()
    assert checks.evaluated_vertices(obj)[:, 2].max() > 1e-3  # so does Refine
    checks.select_only(obj)
    assert bpy.ops.shapedeform.add_handle(location=(1.4, 0.55, 0.0), kind="OVERLAP") == {"FINISHED"}
    assert "reaches none" not in capsys.readouterr().out


def wind_the_other_way(obj, faces):
    """Reverse the winding of ``faces`` (indices), as a flipped normal shows in Blender."""
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bm.faces.ensure_lookup_table()
    bmesh.ops.reverse_faces(bm, faces=[bm.faces[i] for i in faces])
    bm.to_mesh(obj.data)
    bm.free()


@pytest.mark.parametrize("flipped", ["none", "one arm face"])
@pytest.mark.parametrize("graph_mode", ["OWN", "AUTO"])
def test_a_puppets_overlapping_islands_move_apart(addon, flipped, graph_mode):
    """The arm dragged up takes all its own vertices along and none of the body's (those under
    the arm jumped with it, and the arm's over the body stayed behind, where the modifier
    looked points up by their place), the mesh its own graph or, by default, each island an
    outline graph of its own. With one arm face wound the other way, its boundary read as
    pinched and the graph was built from the faces' union, which merged the arm into the body:
    the body moved up to 0.73 with the hand."""
    obj, body = puppet()
    obj.shapedeform.graph_mode = graph_mode
    if flipped == "one arm face":
        wind_the_other_way(obj, [len(obj.data.polygons) - 1])  # the arm's faces come last
    rest = checks.mesh_points(obj).copy()
    pose_puppet(obj)
    if graph_mode == "OWN":
        assert len(obj.shapedeform.cage.data.vertices) == len(rest)  # the mesh is its own graph
    else:
        assert len(obj.shapedeform.cage.data.vertices) > 3 * len(rest)  # an outline graph
    assert_arm_up_body_still(checks.evaluated_mesh_points(obj), rest, np.arange(len(rest)) >= body)


@pytest.mark.parametrize("body", ["whole", "a face flipped", "a hole"])
def test_a_dense_puppets_overlapping_islands_move_apart(addon, monkeypatch, body):
    """Past 2,000 vertices Bind did not ask whether the islands overlap (uniting every triangle
    took 3.2 s at 100,000), and built one outline of them all: the arm was glued to the body
    (QA). Each island's boundary loops say what it covers (a flipped face turns with its
    island; a hole is one of its loops), and the arm moves alone."""
    obj, n_body = puppet(detail=8)
    if body == "a face flipped":
        wind_the_other_way(obj, [0])
    elif body == "a hole":
        bm = bmesh.new()
        bm.from_mesh(obj.data)
        bm.faces.ensure_lookup_table()
        bmesh.ops.delete(bm, geom=[bm.faces[4 * 64 + 4]], context="FACES_ONLY")
        bm.to_mesh(obj.data)
        bm.free()
    body = n_body
    rest = checks.mesh_points(obj).copy()
    assert len(rest) > 2000
    # The islands' loops tell what they cover: their faces are never united (0.74 s at 20,000).
    mesh_source = addon.shapedeform_addon.sources.mesh
    united, union_all, cover = [], mesh_source.shapely.union_all, mesh_source._island_cover

    def counted(geometries, **kw):
        united.append(len(geometries))
        return union_all(geometries, **kw)

    def watched(*args):
        with monkeypatch.context() as patch:
            patch.setattr(mesh_source.shapely, "union_all", counted)
            return cover(*args)

    monkeypatch.setattr(mesh_source, "_island_cover", watched)
    pose_puppet(obj)
    assert united == [2]  # the two islands' shapes, once
    assert_arm_up_body_still(checks.evaluated_mesh_points(obj), rest, np.arange(len(rest)) >= body)


def test_a_handle_at_a_selected_arm_vertex_over_the_body_moves_the_arm_only(addon):
    """Edit Mode, the puppet at rest: a handle added at one selected vertex of the arm, where
    the arm lies over the body, holds the arm alone. Its region took every graph point within
    its radius, the body's under it too, and moving the handle 0.3 tore 41 body points along."""
    obj, n_body = puppet()
    rest = checks.mesh_points(obj).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, (0.0, 0.5, 0.0))  # the body's left end
    checks.add_handle(obj, (3.0, 0.5, 0.0))  # the arm's hand
    elbow = n_body + int(np.argmin(np.linalg.norm(rest[n_body:, :2] - [1.8, 0.3], axis=1)))
    assert np.linalg.norm(rest[:n_body, :2] - rest[elbow, :2], axis=1).min() < 0.1  # the body's near
    moved = moved_by_a_handle_at(obj, rest, elbow, in_edit_mode=True)
    assert moved[elbow] == pytest.approx(0.3, abs=1e-3)
    np.testing.assert_allclose(moved[:n_body], 0.0, atol=1e-4)


def moved_by_a_handle_at(obj, rest, vertex, in_edit_mode):
    """Add a handle at ``vertex`` (in Edit Mode with it alone selected, else at its place as
    shown) and move it 0.3 along y: how far each vertex moved in the plane (v,)."""
    if in_edit_mode:
        checks.select_only(obj)
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.mesh.select_all(action="DESELECT")
        bpy.ops.object.mode_set(mode="OBJECT")
        obj.data.vertices[vertex].select = True
        bpy.ops.object.mode_set(mode="EDIT")
        assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
        bpy.ops.object.mode_set(mode="OBJECT")
    else:
        checks.add_handle(obj, tuple(checks.evaluated_vertices(obj)[vertex]))
    obj.shapedeform.handles[-1].object.location.y += 0.3
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    return np.linalg.norm((checks.evaluated_mesh_points(obj) - rest)[:, :2], axis=1)


def arm_vertex_on_a_body_vertex(rest, n_body):
    """The puppet's arm vertex at (1.5, 0.5), where a body vertex lies too."""
    shared = np.flatnonzero(np.all(np.isclose(rest[:, :2], [1.5, 0.5]), axis=1))
    assert len(shared) == 2 and shared[0] < n_body <= shared[1]
    return int(shared[1])


def test_a_handle_at_a_selected_arm_vertex_on_a_body_vertex_moves_the_arm_only(addon):
    """Edit Mode, the puppet at rest, the arm vertex selected that lies exactly on a body
    vertex: the handle holds the arm, the selected vertex's own island. Its region stayed on the
    piece of the graph point nearest its centre, a tie the body's point won (the lower index):
    the arm vertex did not move and the body moved 0.31."""
    obj, n_body = puppet()
    rest = checks.mesh_points(obj).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, (0.0, 0.5, 0.0))
    checks.add_handle(obj, (3.0, 0.5, 0.0))
    arm = arm_vertex_on_a_body_vertex(rest, n_body)
    moved = moved_by_a_handle_at(obj, rest, arm, in_edit_mode=True)
    assert moved[arm] == pytest.approx(0.3, abs=1e-3)
    np.testing.assert_allclose(moved[:n_body], 0.0, atol=1e-4)


def test_a_handle_added_where_the_arm_is_in_front_of_the_body_moves_the_arm_only(addon):
    """Object Mode, an overlap pin on the hand puts the arm in front of the body: a handle
    added at an arm vertex as shown, where it lies on a body vertex, holds the arm (placing it
    found the arm's triangle; its region then went to the nearest graph point's piece, a tie
    the body's won)."""
    obj, n_body = puppet()
    rest = checks.mesh_points(obj).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, (0.0, 0.5, 0.0))
    checks.add_handle(obj, (3.0, 0.5, 0.0))
    assert bpy.ops.shapedeform.add_handle(location=(2.7, 0.5, 0.0), kind="OVERLAP") == {"FINISHED"}
    obj.shapedeform.handles[-1].object.shapedeform.extent = 1.0
    bpy.context.view_layer.update()
    shown = checks.evaluated_vertices(obj)
    assert shown[n_body:, 2].min() > shown[:n_body, 2].max()  # the arm in front
    arm = arm_vertex_on_a_body_vertex(rest, n_body)
    moved = moved_by_a_handle_at(obj, rest, arm, in_edit_mode=False)
    assert moved[arm] == pytest.approx(0.3, abs=1e-3)
    np.testing.assert_allclose(moved[:n_body], 0.0, atol=1e-4)


def test_a_face_wound_the_other_way_changes_nothing(addon):
    """A grid with one face wound against the others (Blender shows its normal flipped; every
    edge is still used by one or two faces): Graph: Mesh refused it as "not manifold", and
    Automatic rigged its outline instead of the mesh, posing it up to 0.14 away. Both now rig
    the mesh itself and pose it as the same grid wound one way."""
    poses = {}
    for name, flipped, mode in (("Grid", [], "AUTO"), ("Flipped", [0], "OWN"), ("Flipped auto", [0], "AUTO")):
        obj = grid(name)
        wind_the_other_way(obj, flipped)
        obj.shapedeform.graph_mode = mode
        _, right = checks.bind_with_handles(obj, [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0])
        assert len(obj.shapedeform.cage.data.vertices) == len(obj.data.vertices)
        right.location.y += 0.5
        bpy.context.view_layer.update()
        assert obj.shapedeform.status == ""
        poses[name] = checks.evaluated_mesh_points(obj)
    np.testing.assert_allclose(poses["Flipped"], poses["Grid"], atol=1e-4)
    np.testing.assert_allclose(poses["Flipped auto"], poses["Grid"], atol=1e-4)


def _reach_key(addon, obj, body):
    """The puppet's own shape key sliding the arm 0.03 along itself, on: [(part, its rest, arm)]."""
    obj.shape_key_add(name="Basis")
    reach = obj.shape_key_add(name="Reach", from_mix=False)
    for i in range(body, len(obj.data.vertices)):
        reach.data[i].co.x += 0.03
    reach.value = 1.0
    keyed = checks.mesh_points(obj).copy()
    keyed[body:, 0] += 0.03
    return [(obj, keyed, np.arange(len(keyed)) >= body)]


def _body_corner_deleted(addon, obj, body):
    """Edit Mode: the body's corner at (0, 0), far from the arm, deleted (every arm vertex's
    index drops by one)."""
    rest = checks.mesh_points(obj)[1:].copy()
    bpy.ops.object.mode_set(mode="EDIT")
    edited = bmesh.from_edit_mesh(obj.data)
    edited.verts.ensure_lookup_table()
    bmesh.ops.delete(edited, geom=[edited.verts[0]], context="VERTS")
    bmesh.update_edit_mesh(obj.data)
    bpy.ops.object.mode_set(mode="OBJECT")
    return [(obj, rest, np.arange(1, len(rest) + 1) >= body)]


def _separated(addon, obj, body):
    """Edit Mode > Separate > By Loose Parts: the arm an object of its own, following the rig."""
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    assert bpy.ops.mesh.separate(type="LOOSE") == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    parts = [o for o in bpy.data.objects if o.type == "MESH" and o.shapedeform.is_bound]
    assert len(parts) == 2
    return [(part, checks.mesh_points(part).copy(), np.full(len(part.data.vertices), len(part.data.vertices) != body))
            for part in parts]


def _refined(addon, obj, body, level=1):
    """The modifier's Refine at ``level`` (the mesh subdivided before it is deformed); the refined
    points' rest read with the hand put back, their island from the refined mesh's edges."""
    shape_deform = addon.shapedeform_addon
    modifier = shape_deform.rig_format.modifiers_of(obj)[0]
    refine = shape_deform.nodes.input_identifiers(modifier.node_group)[shape_deform.nodes.REFINE_INPUT]
    shape_deform.compat.set_modifier_input(modifier, refine, level)
    obj.update_tag()
    hand = obj.shapedeform.handles[1].object
    hand.location.y -= 1.0
    bpy.context.view_layer.update()
    refined = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    rest = checks.mesh_points(obj, refined).copy()
    edges = np.array([e.vertices[:] for e in refined.edges])
    _, island = connected_components(coo_matrix((np.ones(len(edges)), edges.T), shape=(len(rest),) * 2))
    hand.location.y += 1.0
    is_arm = island == island[body]  # the arm's first vertex keeps its index
    assert is_arm.sum() > len(obj.data.vertices) - body
    return [(obj, rest, is_arm)]


@pytest.mark.parametrize("edit", [_reach_key, _body_corner_deleted, _separated, _refined],
                         ids=["a shape key slides the arm", "a body vertex deleted", "separated", "Refine"])
def test_a_puppets_arm_stays_apart_from_its_body_after_edits(addon, edit, quiet):
    """Once the arm's vertices are no longer the cage's points of their index at their rest
    place (a shape key, Edit Mode, Separate, Refine), each still moves with its own island:
    4 to 31 of the arm's points over the body stayed with the body, a whole drag off, where the
    modifier could tell the islands apart by nothing but their place."""
    obj, body = puppet()
    pose_puppet(obj)
    checks.select_only(obj)
    parts = edit(addon, obj, body)
    bpy.context.view_layer.update()
    for part, rest, is_arm in parts:
        assert part.shapedeform.status == ""
        assert_arm_up_body_still(checks.evaluated_mesh_points(part), rest, is_arm)


@pytest.mark.parametrize("numbered_by", ["this version", "an older version", "an older version, two rigs"])
def test_a_refined_puppet_keeps_its_islands_whatever_first_number_its_rig_drew(addon, monkeypatch, tmp_path,
                                                                               numbered_by, quiet):
    """Refine's subdivision mixes the island numbers in single precision: from a first number
    drawn near 2**24, refined body points came out a number off, the arm's, and flew with it
    (QA: 22 of 81 body points, 3.5 units). Every number now stays under 2**20; here the rig
    draws the largest first number it may, or an older version's rig, numbered near 2**24, is
    numbered anew when its file is opened."""
    shape_deform = addon.shapedeform_addon
    monkeypatch.setattr(shape_deform.rig_format.random, "choice", max)
    obj, body = puppet()
    pose_puppet(obj)
    cages = [obj.shapedeform.cage.data]
    if numbered_by.endswith("two rigs"):  # a second rig of the same mesh reads the same numbers
        checks.select_only(obj)
        assert bpy.ops.object.duplicate(linked=True) == {"FINISHED"}
        second = bpy.context.active_object
        checks.select_only(second)
        assert bpy.ops.shapedeform.unbind() == {"FINISHED"}  # from follower to a rig of its own
        assert bpy.ops.shapedeform.bind() == {"FINISHED"}
        cages.append(second.shapedeform.cage.data)
        assert island_numbers_of(addon, cages[1]).min() == island_numbers_of(addon, cages[0]).min()
    if numbered_by.startswith("an older version"):
        for mesh in (obj.data, *cages):
            islands = island_numbers_of(addon, mesh)
            mesh.attributes[shape_deform.nodes.ISLAND].data.foreach_set("value", islands + 2**24 - 2**20)
        assert island_numbers_of(addon, obj.data).max() > 2**23
        path = str(tmp_path / "puppet.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path)
        bpy.ops.wm.open_mainfile(filepath=path)
        obj = bpy.data.objects["Puppet"]
    assert 0 < island_numbers_of(addon, obj.data).max() < 2**20
    for owner in (o for o in bpy.data.objects if o.data == obj.data and o.shapedeform.is_bound):
        assert set(island_numbers_of(addon, obj.data)) <= set(island_numbers_of(addon, owner.shapedeform.cage.data))
    checks.select_only(obj)
    [(part, rest, is_arm)] = _refined(addon, obj, body, level=3)
    bpy.context.view_layer.update()
    assert part.shapedeform.status == ""
    assert_arm_up_body_still(checks.evaluated_mesh_points(part), rest, is_arm)


def _copy(obj, linked):
    """Shift+D (``linked`` False) or Alt+D of ``obj``: the copy follows its rig."""
    checks.select_only(obj)
    assert bpy.ops.object.duplicate(linked=linked) == {"FINISHED"}
    return bpy.context.active_object


def _unbind(obj):
    checks.select_only(obj)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}


def test_a_puppets_islands_last_through_reload_duplicates_join_and_undo_and_go_on_unbind(addon, tmp_path, quiet):
    """Bind keeps each vertex's island in the mesh, hidden; it goes with the mesh (saved, copied,
    joined to, undone) and Unbind removes it, from a copy's own mesh too, leaving the mesh as it
    was; while another bound object shares the mesh, it stays for that one."""
    obj, body = puppet()
    before = checks.snapshot()
    rest = checks.mesh_points(obj).copy()
    pose_puppet(obj)
    added = {a.name for a in obj.data.attributes} - set(before["mesh Puppet"][1])
    assert added and all(name.startswith(".") for name in added)  # hidden from the attribute lists
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    assert added.isdisjoint(a.name for a in evaluated.attributes)  # nor left by Apply or an export
    path = str(tmp_path / "puppet.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Puppet"]
    own_copy, shared_copy = _copy(obj, linked=False), _copy(obj, linked=True)
    checks.select_only(obj)
    edited = _body_corner_deleted(addon, obj, body)[0]  # the shared copy's mesh too
    square, square_faces = quads(1, 1, 0.2, 0.2, 2.6, 0.4, 0)  # on the arm, off the body
    plain = bpy.data.objects.new("Plain", bpy.data.meshes.new("Plain"))
    plain.data.from_pydata(square, [], square_faces)
    bpy.context.scene.collection.objects.link(plain)
    join_into(obj, plain)
    joined = (np.concatenate([edited[1], np.array(square)]), np.concatenate([edited[2], np.ones(4, bool)]))
    for part, (part_rest, is_arm) in ((obj, joined), (shared_copy, joined),
                                      (own_copy, (rest, np.arange(len(rest)) >= body))):
        assert_arm_up_body_still(checks.evaluated_mesh_points(part), part_rest, is_arm)

    for copy in (own_copy, shared_copy):
        _unbind(copy)
        np.testing.assert_array_equal(checks.evaluated_mesh_points(copy), checks.mesh_points(copy))
    assert sorted(a.name for a in own_copy.data.attributes) == before["mesh Puppet"][1]
    assert_arm_up_body_still(checks.evaluated_mesh_points(obj), *joined)  # the shared mesh keeps them

    bpy.ops.ed.undo_push(message="before unbind")
    _unbind(obj)
    assert sorted(a.name for a in obj.data.attributes) == before["mesh Puppet"][1]
    bpy.ops.ed.undo_push(message="unbound")
    assert bpy.ops.ed.undo() == {"FINISHED"}
    obj = bpy.data.objects["Puppet"]
    bpy.context.view_layer.update()
    assert obj.shapedeform.is_bound
    assert_arm_up_body_still(checks.evaluated_mesh_points(obj), *joined)


def test_a_puppet_bound_by_an_older_version_poses_as_it_did(addon):
    """A rig bound before vertices kept their islands (neither the mesh nor the cage has them)
    poses exactly as the rig bound now: unedited, its vertices are its cage's points (the mesh
    was its own graph, as older versions made it)."""
    obj, body = puppet()
    obj.shapedeform.graph_mode = "OWN"
    pose_puppet(obj)
    posed = checks.evaluated_mesh_points(obj).copy()
    island = addon.shapedeform_addon.nodes.ISLAND
    for mesh in (obj.data, obj.shapedeform.cage.data):
        mesh.attributes.remove(mesh.attributes[island])
        mesh.update()
    bpy.context.view_layer.update()
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), posed, atol=1e-6)


@pytest.mark.parametrize("cage", ["posed", "deleted by hand"])
def test_applying_a_puppets_modifier_leaves_no_islands(addon, cage):
    """The vertices' islands are the rig's: Apply gives a mesh without them, posed or, its
    cage deleted by hand, as it was (the group passed that geometry through with them)."""
    obj, _ = puppet()
    rest = checks.mesh_points(obj).copy()
    pose_puppet(obj)
    island = addon.shapedeform_addon.nodes.ISLAND
    assert island in obj.data.attributes
    if cage == "deleted by hand":
        bpy.data.objects.remove(obj.shapedeform.cage)
        bpy.context.view_layer.update()
        np.testing.assert_array_equal(checks.evaluated_mesh_points(obj), rest)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.object.modifier_apply(modifier=obj.modifiers[0].name) == {"FINISHED"}
    assert island not in obj.data.attributes


def test_a_puppet_joined_into_a_plain_mesh_leaves_it_no_islands(addon):
    """Ctrl+J of a posed puppet into a mesh no rig deforms: Join merges the meshes' attributes,
    and the hidden islands stayed on a mesh nothing would ever unbind."""
    obj, _ = puppet()
    pose_puppet(obj)
    plain = grid("Plain")
    join_into(plain, obj)
    assert not plain.shapedeform.is_bound
    assert addon.shapedeform_addon.nodes.ISLAND not in plain.data.attributes


def test_pixels_touching_at_corners_are_rigged_by_their_outline(addon):
    """A sprite modelled pixel by pixel: squares that touch only at corners. The mesh cannot be
    its own graph (its boundary pinches there; the Mesh choice says so and what to do), and the
    Outline graph is built from the faces' union (both were refused as "not manifold")."""
    index, faces = {}, []
    for i, j in ((0, 0), (1, 1), (2, 0), (2, 2), (3, 1)):  # a zigzag of unit squares, corners shared
        corners = [(i, j, 0.0), (i + 1, j, 0.0), (i + 1, j + 1, 0.0), (i, j + 1, 0.0)]
        faces.append([index.setdefault(corner, len(index)) for corner in corners])
    mesh = bpy.data.meshes.new("Sprite")
    mesh.from_pydata(list(index), [], faces)
    mesh.validate()
    bpy.ops.object.select_all(action="DESELECT")
    obj = bpy.data.objects.new("Sprite", mesh)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.shapedeform.graph_mode = "OWN"
    with pytest.raises(RuntimeError, match="use the Outline graph"):
        bpy.ops.shapedeform.bind()
    obj.shapedeform.graph_mode = "AUTO"
    rest = checks.mesh_points(obj).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    handle = checks.add_handle(obj, (2.5, 0.5, 0.0))
    handle.location.y += 0.25
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    moved = checks.evaluated_mesh_points(obj) - rest
    middle = np.all((rest[:, :2] >= 2.0) & (rest[:, :2] <= 3.0), axis=1) & (rest[:, 1] <= 1.0)
    np.testing.assert_allclose(moved[middle, 1], 0.25, atol=1e-3)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    np.testing.assert_array_equal(checks.mesh_points(obj), rest)


def test_a_bevelled_curve_converted_to_a_mesh_is_rigged_by_what_the_plane_shows(addon):
    """A Bezier circle bevelled into a tube, converted to a mesh: a closed surface with no
    boundary, whose faces lie on one another in the plane. The union of its faces is a ring,
    but faces meeting edge to edge left slits of rounding (1e-11 across) in it, and Bind said
    "ring 3 has fewer than 3 distinct points"; the ring now poses as a ring."""
    bpy.ops.curve.primitive_bezier_circle_add(radius=1.0)
    circle = bpy.context.active_object
    circle.data.bevel_depth = 0.05
    assert bpy.ops.object.convert(target="MESH") == {"FINISHED"}
    obj = bpy.context.active_object
    rest = checks.mesh_points(obj).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    cage = checks.mesh_points(obj.shapedeform.cage)[:, :2]
    radii = np.linalg.norm(cage, axis=1)
    assert radii.min() > 0.9 and radii.max() < 1.1  # a ring, holes of rounding left out
    _, right = [checks.add_handle(obj, (x, 0.0, 0.0)) for x in (-1.0, 1.0)]
    right.location.y += 0.3
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    moved = checks.evaluated_mesh_points(obj) - rest
    assert np.all(np.isfinite(moved)) and moved[rest[:, 0] > 0.9, 1].min() > 0.25


def test_long_thin_faces_are_flagged_at_bind_and_refine_keeps_them_from_folding(addon, capfd):
    """Issue 15, item 5: slivers spanning a bent stretch keep straight edges and turn over,
    although the map under them does not fold; the modifier's Refine subdivides them first."""
    top = [(x, 0.3, 0.0) for x in np.linspace(0.0, 4.0, 9)]
    mesh = bpy.data.meshes.new("Strip")  # a fan of triangles, each spanning the strip's length
    mesh.from_pydata([(0.0, 0.0, 0.0), (4.0, 0.0, 0.0)] + top, [], [(0, 1, 10)] + [(0, 3 + i, 2 + i) for i in range(8)])
    obj = bpy.data.objects.new("Strip", mesh)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert "long thin faces" in capfd.readouterr().out
    checks.add_handle(obj, (0.1, 0.15, 0.0))
    bend = checks.add_handle(obj, (3.9, 0.15, 0.0))
    shape_deform = addon.shapedeform_addon
    modifier = shape_deform.rig_format.modifiers_of(obj)[0]
    refine = shape_deform.nodes.input_identifiers(modifier.node_group)["Refine"]
    assert shape_deform.compat.modifier_input(modifier, refine) == 0  # off by default
    flipped = {}
    for level in (0, 3):
        shape_deform.compat.set_modifier_input(modifier, refine, level)
        obj.update_tag()
        bend.location, bend.rotation_euler.z = (3.9, 0.15, 0.0), 0.0
        bpy.context.view_layer.update()
        rest_areas = _evaluated_signed_areas(obj)
        bend.location, bend.rotation_euler.z = (2.0, 2.0, 0.0), 2.0
        bpy.context.view_layer.update()
        flipped[level] = _flipped_area_fraction(obj, rest_areas)
    assert flipped[0] > 0.1
    assert flipped[3] < 0.5 * flipped[0]
    assert len(obj.data.vertices) == 11  # subdivided in the modifier only


# -- adversarial shapes --------------------------------------------------------------------------

def flat_mesh(name, points, faces):
    """A mesh object of 2D ``points`` in the XY plane, linked to the scene and active."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(x, y, 0.0) for x, y in points], [], faces)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    checks.select_only(obj)
    return obj


def strip(width, height, columns, rows=1):
    """Points and quads of a ``width`` x ``height`` grid centred on the origin."""
    points = [(width * (i / columns - 0.5), height * (j / rows - 0.5))
              for j in range(rows + 1) for i in range(columns + 1)]
    faces = [[j * (columns + 1) + i + k for k in (0, 1, columns + 2, columns + 1)]
             for j in range(rows) for i in range(columns)]
    return points, faces


def test_a_hairline_strip_binds_and_takes_handles(addon, quiet):
    """A strip 30,000 times longer than wide: Add Handle raised Qhull's error with a traceback
    (the coarse copy a solve may start from could not be triangulated), and so did every later
    update; a strip 1e6 times longer was refused as having "no faces" (joining coincident
    vertices within 1e-6 of its length joined each face's top and bottom)."""
    obj = flat_mesh("Sliver", *strip(3e4, 1.0, 50))
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert bpy.ops.shapedeform.add_handle(location=(-1.5e4, 0.0, 0.0)) == {"FINISHED"}
    handle = checks.add_handle(obj, (1.5e4, 0.0, 0.0))
    handle.location.y += 1.0
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    assert np.all(np.isfinite(checks.evaluated_mesh_points(obj)))
    flat_mesh("Strip", *strip(1e6, 1.0, 50))
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}


def test_blenders_plane_takes_a_handle_at_each_corner(addon):
    """Add > Mesh > Plane (four corners, nothing inside) is rigged by its outline: a handle at
    a corner moves that corner (with its own graph of four points a corner's handle took three
    corners, moved them rigidly, and a third handle was refused)."""
    bpy.ops.mesh.primitive_plane_add()
    plane = bpy.context.active_object
    corners = checks.mesh_points(plane).copy()
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    handles = [checks.add_handle(plane, checks.world(plane, c)) for c in corners]
    handles[0].location.x -= 0.5
    bpy.context.view_layer.update()
    moved = np.linalg.norm((checks.evaluated_mesh_points(plane) - corners)[:, :2], axis=1)
    np.testing.assert_allclose(moved, [0.5, 0.0, 0.0, 0.0], atol=1e-4)


def test_a_degenerate_face_beside_the_shape_is_left_out(addon):
    """A grid and, beside it, a face whose corners are on one line (what Degenerate Dissolve is
    for): Bind refused the whole mesh ("ring 1 has zero area"); the flat face is left out of the
    outline and its points follow the nearest part."""
    points, faces = strip(2.0, 1.0, 4, 2)
    n = len(points)
    obj = flat_mesh("Grid", points + [(1.5, 0.0), (2.0, 0.0), (2.5, 0.0)], faces + [[n, n + 1, n + 2]])
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert obj.shapedeform.status == ""


def test_a_pose_does_not_depend_on_the_shapes_size(addon):
    """The same grid at two sizes, dragged by the same fraction of its size: the same pose (a
    handle's region took two of a vertex's four equally near neighbours, chosen by rounding, so
    the poses differed by 1% of the width)."""
    poses = []
    for width in (2.0, 0.2):
        obj = flat_mesh(f"Grid {width}", *strip(width, width / 2, 12, 6))
        rest = checks.mesh_points(obj).astype(float)
        assert bpy.ops.shapedeform.bind() == {"FINISHED"}
        checks.add_handle(obj, (-width / 2, 0.0, 0.0))
        right = checks.add_handle(obj, (width / 2, 0.0, 0.0))
        right.matrix_world.translation = Vector((width / 2, 0.3 * width / 2, 0.0))
        bpy.context.view_layer.update()
        poses.append((checks.evaluated_mesh_points(obj).astype(float) - rest)[:, :2] / width)
    assert np.abs(poses[0] - poses[1]).max() < 1e-4


def test_a_rigged_puppet_joined_into_another_follows_the_parts_it_lies_on(addon):
    """Ctrl+J of one bound puppet into another: the joined vertices kept their own rig's island
    numbers, which the other rig read as its own, so the joined arm's vertices lying on the
    body moved up 1.0 with the other's arm. Numbered apart, they are looked up by their place."""
    island = addon.shapedeform_addon.nodes.ISLAND
    first, _ = puppet()
    pose_puppet(first)
    second, _ = puppet()
    second.name = "Second"
    second.location = (-1.2, 0.0, 0.0)
    bpy.context.view_layer.update()
    checks.select_only(second)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    numbers = [np.zeros(len(o.data.vertices), np.int32) for o in (first, second)]
    for obj, values in zip((first, second), numbers):
        obj.data.attributes[island].data.foreach_get("value", values)
    assert not set(numbers[0]) & set(numbers[1])  # each rig numbers its islands apart
    assert_joined_arm_stays(addon, first, second)


def island_numbers_of(addon, mesh):
    return addon.shapedeform_addon.rig_format.islands_of(mesh)


def assert_joined_arm_stays(addon, first, second):
    """Ctrl+J of posed puppet ``second``, placed 1.2 left of ``first`` (at the origin), into
    ``first``: the vertices of ``second``'s arm lying on ``first``'s body stay where they are.
    Where its islands are numbered as ``first``'s, ``first``'s rig reads them as its own arm's
    and moves them up 1.0."""
    numbers = island_numbers_of(addon, second.data)
    joined_rest = checks.mesh_points(second) + [-1.2, 0.0, 0.0]
    arm = numbers == numbers.max()
    count = len(first.data.vertices)
    join_into(first, second)
    moved = checks.evaluated_mesh_points(first)[count:, :2] - joined_rest[:, :2]
    on_body_only = arm & (joined_rest[:, 0] < 1.15)  # left of the first puppet's arm
    assert on_body_only.sum() >= 4
    np.testing.assert_allclose(moved[on_body_only], 0.0, atol=1e-3)


def test_two_rigs_of_one_puppet_mesh_number_its_islands_alike(addon):
    """Alt+D of a puppet before Bind, each bound: two rigs of one mesh. The second Bind wrote
    its own numbers over the mesh's, so the first rig knew none of its vertices: with a shape
    key sliding the arm, 8 of its 21 arm vertices stayed behind with the body, 1.0 off."""
    first, body = puppet()
    checks.select_only(first)
    assert bpy.ops.object.duplicate(linked=True) == {"FINISHED"}
    second = bpy.context.active_object
    second.location.y -= 3.0
    pose_puppet(first)
    checks.select_only(second)
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    cage_numbers = island_numbers_of(addon, first.shapedeform.cage.data)
    assert set(island_numbers_of(addon, first.data)) <= set(cage_numbers)
    np.testing.assert_array_equal(island_numbers_of(addon, second.shapedeform.cage.data), cage_numbers)
    [(_, keyed, is_arm)] = _reach_key(addon, first, body)
    bpy.context.view_layer.update()
    assert_arm_up_body_still(checks.evaluated_mesh_points(first), keyed, is_arm)


def test_a_copy_with_a_rig_of_its_own_numbers_its_islands_apart(addon):
    """Shift+D of a posed puppet with its handles gives the copy a rig of its own, whose cage
    kept the original's island numbers: joined back into the original, the copy's arm vertices
    lying on the original's body moved up 1.0 with the original's arm."""
    from test_handles_driver import duplicate

    first, _ = puppet()
    pose_puppet(first)
    second = duplicate([first] + [item.object for item in first.shapedeform.handles], first)
    rig_format = addon.shapedeform_addon.rig_format
    assert rig_format.is_owner(second) and second.shapedeform.cage != first.shapedeform.cage
    numbers = [island_numbers_of(addon, o.shapedeform.cage.data) for o in (first, second)]
    assert not set(numbers[0]) & set(numbers[1])
    np.testing.assert_array_equal(np.unique(island_numbers_of(addon, second.data)), np.unique(numbers[1]))
    second.location.x -= 1.2
    bpy.context.view_layer.update()
    assert_joined_arm_stays(addon, first, second)


def posed_puppet_library(addon, tmp_path, refine=None, follower=False):
    """A posed puppet (:func:`pose_puppet`) in a collection "Character", its modifier's Refine
    set to ``refine`` if given, with a Shift+D copy ("Puppet Copy", a follower) if
    ``follower``, saved in a library file; then a new empty file. Returns the library's path."""
    from test_handles_driver import duplicate

    obj, _ = puppet()
    character = bpy.data.collections.new("Character")
    bpy.context.scene.collection.children.link(character)
    bpy.context.scene.collection.objects.unlink(obj)
    character.objects.link(obj)
    pose_puppet(obj)
    if refine is not None:
        checks.refine(addon.shapedeform_addon, obj, refine)
    if follower:
        duplicate([obj], obj).name = "Puppet Copy"
    library = str(tmp_path / "puppet.blend")
    bpy.ops.wm.save_as_mainfile(filepath=library)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    return library


def test_a_puppet_appended_twice_numbers_its_copies_islands_apart(addon, tmp_path, quiet):
    """A posed puppet appended twice (no Reuse Data): both copies came with the library's island
    numbers, so joining one into the other moved 12 of the joined arm's vertices up 1.0 with the
    other copy's arm. The copy appended second is numbered apart, its follower's mesh too."""
    library = posed_puppet_library(addon, tmp_path, follower=True)
    for _ in range(2):
        assert bpy.ops.wm.append(directory=library + "/Collection/", filename="Character") == {"FINISHED"}
        bpy.context.view_layer.update()
    first, second = bpy.data.objects["Puppet"], bpy.data.objects["Puppet.001"]
    numbers = [island_numbers_of(addon, o.shapedeform.cage.data) for o in (first, second)]
    assert not set(numbers[0]) & set(numbers[1])
    for obj in (second, bpy.data.objects["Puppet Copy.001"]):
        np.testing.assert_array_equal(np.unique(island_numbers_of(addon, obj.data)), np.unique(numbers[1]))
    second.location.x -= 1.2
    bpy.context.view_layer.update()
    assert_joined_arm_stays(addon, first, second)


def test_an_overridden_puppet_keeps_its_pose_when_the_library_binds_it_again(addon, tmp_path, quiet):
    """The library binds its puppet again on the same graph, which numbers its islands anew,
    after a shot posed an override of it (Refine on): the shot's copy of the cage kept the old
    numbers, none of which the mesh's vertices had any more, and 14 of 218 points moved up to
    1.0 from the pose the same handles gave before."""
    library = posed_puppet_library(addon, tmp_path, refine=1)
    with bpy.data.libraries.load(library, link=True) as (_, linked):
        linked.collections = ["Character"]
    linked.collections[0].override_hierarchy_create(bpy.context.scene, bpy.context.view_layer)
    bpy.context.view_layer.update()
    obj = bpy.context.scene.objects["Puppet"]
    posed = checks.evaluated_mesh_points(obj).copy()  # the hand up 1.0, as the library has it
    obj.shapedeform.handles[1].object.location.y -= 0.5  # the shot's own copy of the cage
    bpy.context.view_layer.update()
    assert obj.shapedeform.cage.data.library is None
    shot = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=shot)

    bpy.ops.wm.open_mainfile(filepath=library)
    rigged = bpy.data.objects["Puppet"]
    numbers = island_numbers_of(addon, rigged.data)
    checks.select_only(rigged)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    for place in ((0.0, 0.5, 0.0), (3.0, 0.5, 0.0)):  # the same handles, not moved
        checks.add_handle(rigged, place)
    checks.refine(addon.shapedeform_addon, rigged, 1)
    assert not set(island_numbers_of(addon, rigged.data)) & set(numbers)
    bpy.ops.wm.save_mainfile()

    bpy.ops.wm.open_mainfile(filepath=shot)
    obj = bpy.context.scene.objects["Puppet"]
    obj.shapedeform.handles[1].object.location.y += 0.5
    bpy.context.view_layer.update()
    np.testing.assert_allclose(checks.evaluated_mesh_points(obj), posed, atol=1e-4)
