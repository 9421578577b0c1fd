"""solver.rigging.outline and solver.rigging.silhouette: mesh boundaries, Bezier outlines, stroke
and image silhouettes, and the map that carries a picture's UVs onto its cut-out."""

import itertools

import numpy as np
import pytest
import shapely
from scipy import ndimage

from solver.rigging.handles import apply_affine
from solver.rigging.outline import boundary_loops, refine_level, sample_bezier, sample_nurbs, with_area, wound_alike
from solver.rigging.silhouette import image_cutout, map_by_triangles, specks, stroke_silhouette
from solver.shapes import shape_geometry

from sample_shapes import disk


def grid_triangles(nx, ny):
    index = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    a, b, c, d = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, 1:].ravel(), index[1:, :-1].ravel()
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def test_boundary_loops_of_a_grid_with_a_hole():
    triangles = grid_triangles(3, 3)
    # Drop the middle square's two triangles: a hole.
    keep = ~np.isin(np.arange(len(triangles)), [4, 13])
    loops = boundary_loops(triangles[keep])
    assert sorted(len(loop) for loop in loops) == [4, 12]


def test_faces_wound_against_their_neighbours_leave_the_boundary_as_it_is():
    """A face wound the other way (a normal flipped in Blender) on the boundary of a grid with
    a hole: the same loops as the grid wound one way (it read as a pinched boundary). Several
    faces turned, in either piece (the second wound the other way throughout), change nothing."""
    grid = grid_triangles(3, 3)
    holed = grid[~np.isin(np.arange(len(grid)), [4, 13])]
    other = grid + holed.max() + 1
    triangles = np.concatenate([holed, other[:, ::-1]])
    expected = sorted(sorted(loop.tolist()) for loop in boundary_loops(triangles))
    for flipped in ([0], [0, 5, 20], [0, len(holed)]):
        mixed = triangles.copy()
        mixed[flipped] = mixed[flipped][:, ::-1]
        assert sorted(sorted(loop.tolist()) for loop in boundary_loops(mixed)) == expected
        # Every shared edge is run both ways: each piece is wound one way.
        directed = np.concatenate([wound_alike(mixed)[:, [k, (k + 1) % 3]] for k in range(3)])
        assert len(np.unique(directed, axis=0)) == len(directed)


def test_a_flat_face_follows_its_neighbours_winding():
    """A face whose corners lie on one line (no winding in the plane) on the boundary of a
    strip wound against the plane's own orientation: it keeps the strip's winding."""
    strip = np.array([[0, 2, 1], [1, 2, 3], [1, 3, 4]])  # 4 lies between 1 and 3: flat
    assert np.array_equal(wound_alike(strip), strip)
    for flipped in ([2], [0, 1]):
        mixed = strip.copy()
        mixed[flipped] = mixed[flipped][:, ::-1]
        fixed = wound_alike(mixed)
        assert np.array_equal(fixed, strip) or np.array_equal(fixed, strip[:, ::-1])


def test_boundary_loops_refuse_closed_and_nonmanifold():
    tetrahedron = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]])
    with pytest.raises(ValueError, match="no boundary"):
        boundary_loops(tetrahedron)
    bowtie = np.array([[0, 1, 2], [0, 3, 4]])
    with pytest.raises(ValueError, match="not manifold"):
        boundary_loops(bowtie)
    with pytest.raises(ValueError, match="no faces"):
        boundary_loops(np.empty((0, 3), int))


def test_bezier_sampling_hits_control_points_and_is_a_circle():
    # Blender's Bezier circle: 4 points, handles at 0.5523 of the radius.
    k = 0.5522847498
    points = np.array([[1, 0], [0, 1], [-1, 0], [0, -1.0]])
    tangent = np.array([[0, 1], [-1, 0], [0, -1], [1, 0.0]])
    curve = sample_bezier(points, points - k * tangent, points + k * tangent, cyclic=True, resolution=8)
    assert len(curve) == 32
    np.testing.assert_allclose(curve[::8], points)
    np.testing.assert_allclose(np.linalg.norm(curve, axis=1), 1.0, atol=3e-4)
    open_curve = sample_bezier(points, points - k * tangent, points + k * tangent, cyclic=False, resolution=8)
    assert len(open_curve) == 25 and np.allclose(open_curve[-1], points[-1])


def test_nurbs_sampling_draws_the_weighted_circle():
    """Blender's NURBS circle: eight points round a square, the corners weighted 1/sqrt(2), order
    3 with Endpoint and Bezier knots, is a circle through the edges' midpoints (the rig's outline
    was the square, reaching 1.41 for a circle of 1, QA)."""
    square = np.array([[0, -1], [-1, -1], [-1, 0], [-1, 1], [0, 1], [1, 1], [1, 0], [1, -1.0]])
    weights = np.where(np.abs(square).sum(axis=1) == 2, np.sqrt(0.5), 1.0)
    circle = sample_nurbs(square, weights, 3, cyclic=True, endpoint=True, bezier=True, resolution=12)
    assert len(circle) == 48
    np.testing.assert_allclose(np.linalg.norm(circle, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(circle[::12], square[::2], atol=1e-12)


@pytest.mark.parametrize("order", [2, 3, 4, 5])
@pytest.mark.parametrize("cyclic", [False, True])
def test_nurbs_sampling_properties_hold_for_any_spline(order, cyclic):
    rng = np.random.default_rng(order + 10 * cyclic)
    points, weights = rng.normal(size=(7, 2)), rng.uniform(0.2, 3.0, 7)
    for endpoint, per_span in itertools.product((False, True), (False, True)):
        curve = sample_nurbs(points, weights, order, cyclic, endpoint=endpoint, resolution=6, per_span=per_span)
        # Positive weights keep every sample inside the points' hull; equal scaling changes nothing.
        hull = shapely.MultiPoint(points).convex_hull.buffer(1e-9)
        assert all(hull.contains(shapely.Point(p)) for p in curve)
        np.testing.assert_allclose(sample_nurbs(points, 4 * weights, order, cyclic, endpoint=endpoint, resolution=6,
                                                per_span=per_span), curve, atol=1e-12)
        if endpoint and not cyclic:  # a clamped open spline starts and ends at its end points
            np.testing.assert_allclose(curve[[0, -1]], points[[0, -1]], atol=1e-12)
    if order == 2:  # straight spans through the points
        np.testing.assert_allclose(sample_nurbs(points, weights, 2, cyclic, resolution=6)[::6], points, atol=1e-12)
    # A spline Blender cannot draw as a curve is drawn through its points.
    too_few = points[:order - 1]
    np.testing.assert_array_equal(sample_nurbs(too_few, weights[:order - 1], order, cyclic), too_few)


def test_stroke_silhouette_is_the_swept_and_filled_union():
    line = np.array([[0, 0], [4, 0.0]])
    ring = disk(1.0, 32, centre=(8, 0))
    points = np.concatenate([line, ring])
    rings = stroke_silhouette(points, [0, 2, 34], radii=np.full(34, 0.5), cyclic=[False, True])
    area = shape_geometry(rings).area
    expected = 4 * 1.0 + np.pi * 0.25 + shapely.Polygon(ring).buffer(0.5, quad_segs=4).area
    assert area == pytest.approx(expected, rel=0.02)
    assert len(rings) == 2  # two islands, no holes: the fill covers the ring's inside


def test_stroke_silhouette_sweeps_strokes_only_outside_the_areas():
    """A curve's closed splines with holes (an O) and open ones: a tail beside it is swept, a
    line drawn inside the ring (near its edge) adds nothing, and the hole stays a hole."""
    outer, hole = disk(1.0, 64), disk(0.5, 32)[::-1]
    tail = np.array([[1.0, 0.0], [3.0, 0.0]])
    inside = np.array([[0.0, -0.7], [0.0, -0.98]])
    rings = stroke_silhouette(np.concatenate([tail, inside]), [0, 2, 4], np.full(4, 0.1), areas=[outer, hole])
    area = shape_geometry(rings).area
    ring_area = shape_geometry([outer, hole]).area
    assert area == pytest.approx(ring_area + 2 * 0.2 + 0.5 * np.pi * 0.01, rel=0.01)
    assert len(rings) == 2  # the outline (the tail joined to it) and the hole
    assert max(np.linalg.norm(ring, axis=1).max() for ring in rings) == pytest.approx(3.1, abs=1e-6)


@pytest.mark.parametrize("ends", ["drawn over each other", "touching", "a gap wider than the line"])
def test_an_open_stroke_covers_what_it_goes_round_by_itself(ends):
    """The draw tool leaves an outline closed by hand open: its sweep was a ring, and what was
    drawn inside it (eyes) no part of the shape (QA). What one stroke encloses by itself is
    covered, as a closed stroke's fill; a gap between its ends wider than the line is not
    closed, nor is a hole between strokes."""
    first, last = {"drawn over each other": (0.0, 2 * np.pi + 0.1), "touching": (0.05, 2 * np.pi),
                   "a gap wider than the line": (0.3, 2 * np.pi)}[ends]
    t = np.linspace(first, last, 90)
    outline = np.column_stack([np.cos(t), np.sin(t)])
    shape = shape_geometry(stroke_silhouette(outline, [0, 90], np.full(90, 0.03)))
    assert shape.contains(shapely.Point(0.0, 0.0)) == (ends != "a gap wider than the line")
    halves = np.concatenate([outline[:45], outline[44:]])  # the same ring, in two strokes
    apart = shape_geometry(stroke_silhouette(halves, [0, 45, 91], np.full(91, 0.03)))
    assert not apart.contains(shapely.Point(0.0, 0.0))


def test_stroke_silhouette_refuses_nothing():
    with pytest.raises(ValueError, match="zero radius"):
        stroke_silhouette(np.array([[0, 0], [1, 0.0]]), [0, 2], np.zeros(2))


def test_image_cutout_covers_every_visible_pixel_and_stays_in_the_picture():
    image = np.zeros((40, 60, 4), np.float32)
    yy, xx = np.mgrid[:40, :60]
    visible = (xx - 30) ** 2 + (yy - 20) ** 2 < 15 ** 2
    visible &= ~((xx - 30) ** 2 + (yy - 20) ** 2 < 5 ** 2)   # a ring: the cut-out has a hole
    visible |= (xx < 3) & (yy < 3)                            # touching the picture's corner
    image[..., 3] = visible * 0.8
    shape = shape_geometry(image_cutout(image))
    centres = shapely.points(xx[visible] + 0.5, yy[visible] + 0.5)
    pixels = shapely.box(xx[visible], yy[visible], xx[visible] + 1, yy[visible] + 1)
    assert shapely.contains(shape.buffer(1e-9), pixels).all()
    assert shapely.box(0, 0, 60, 40).buffer(1e-9).contains(shape)
    assert not shape.contains(shapely.Point(30, 20))  # the hole stays a hole
    assert len(centres) > 0


def test_a_repeating_pictures_cutout_takes_in_the_opposite_edges_and_is_otherwise_the_same():
    """A picture that repeats shows, along each edge, the opposite edge filtered in: its cut-out
    covers pixels there that the far edge's visible pixels reach within the margin, and is the
    plain cut-out where nothing touches an edge."""
    image = np.zeros((40, 60), np.float32)
    image[10:20, 20:30] = 1.0
    for same, plain in zip(image_cutout(image, wrap=True), image_cutout(image), strict=True):
        np.testing.assert_array_equal(same, plain)
    image[25:30, 58:] = image[38:, 5:9] = 1.0  # touching the right and the top edge
    plain, wrapped = shape_geometry(image_cutout(image)), shape_geometry(image_cutout(image, wrap=True))
    far = shapely.box(0, 25, 0.5, 30), shapely.box(5, 0, 9, 0.5)  # where Linear filtering reaches
    assert not any(plain.intersects(box) for box in far)
    assert all(wrapped.buffer(1e-9).contains(box) for box in far)
    assert shapely.box(0, 0, 60, 40).buffer(1e-9).contains(wrapped)
    assert wrapped.contains(plain.buffer(-1e-6))


@pytest.mark.parametrize("window", [None, [(0.0, 0.0), (700.0, 0.0), (700.0, 600.0), (0.0, 600.0)]])
def test_a_pictures_graph_covers_every_visible_pixel_within_what_the_plane_shows(window):
    """A cut-out's graph is the mesh that shows the picture: simplified to a coarse graph's
    spacing (a detail of 1.6 pixels here, 3 at 4,096), it lost a 1-pixel line, a 2 x 2 dot and
    slivers of the outline's pixels. Covering, it keeps them all, and stays in the picture and
    in the window the plane's UVs show."""
    from solver.outline import outline_graph
    from solver.rigging.silhouette import shown_frame

    yy, xx = np.mgrid[:512, :768]
    visible = (xx - 300) ** 2 + (yy - 260) ** 2 < 200 ** 2
    visible[40, 100:700] = True    # a whisker, one pixel wide, crossing the window's edge
    visible[500:502, 600:602] = True
    visible[200:300, 0:20] = True  # at the picture's edge
    rings = image_cutout(visible.astype(np.float32), window=window)
    frame = shown_frame(768, 512, window)
    graph = outline_graph(rings, 20, cover_within=frame)
    shape = shape_geometry([graph.points[loop] for loop in graph.boundary_loops]).buffer(1e-6)
    shown = visible & ((xx < 699) & (yy < 599) if window else True)
    pixels = shapely.box(xx[shown], yy[shown], xx[shown] + 1, yy[shown] + 1)
    assert shapely.contains(shape, pixels).all()
    assert shape_geometry(frame).buffer(1e-6).contains(shape)
    assert graph.n < 200  # as coarse as simplifying alone makes it (87 points)
    simplified = outline_graph(rings, 20)
    alone = shape_geometry([simplified.points[loop] for loop in simplified.boundary_loops]).buffer(1e-6)
    assert not shapely.contains(alone, pixels).all()  # what simplifying alone loses


def test_a_picture_of_nothing_but_specks_is_refused_as_such():
    """Faint specks alone (alpha 0.5 and 0.3) were refused as if the picture were transparent."""
    image = np.zeros((20, 30), np.float32)
    image[5, 5], image[12, 20] = 0.5, 0.3
    with pytest.raises(ValueError, match="its only visible pixels are specks"):
        image_cutout(image)
    with pytest.raises(ValueError, match="is the picture fully transparent"):
        image_cutout(np.zeros((20, 30), np.float32))


def test_image_cutout_leaves_out_dust_nobody_sees_and_keeps_a_single_opaque_pixel():
    rng = np.random.default_rng(0)
    image = np.zeros((120, 120, 4), np.float32)
    yy, xx = np.mgrid[:120, :120]
    disc = (xx - 60) ** 2 + (yy - 60) ** 2 < 30 ** 2
    image[..., 3][disc] = 1.0
    dust = (rng.random((120, 120)) < 0.02) & ~disc             # specks at 5/255: invisible
    image[..., 3][dust] = 0.02
    assert len(shapely.get_parts(shape_geometry(image_cutout(image)))) == 1
    count, strongest = specks(image)  # what is left out can be told
    assert count == ndimage.label(dust | disc, structure=np.ones((3, 3), bool))[1] - 1 and strongest == pytest.approx(0.02)
    # Only the part a window shows: a quarter of the picture holds about a quarter of the specks.
    quarter = specks(image, window=[[0, 0], [60, 0], [60, 60], [0, 60]])[0]
    groups = ndimage.label(dust | disc, structure=np.ones((3, 3), bool))[0]
    assert 0 < quarter < count and quarter == len(set(groups[:60, :60][dust[:60, :60]]) - {groups[60, 60]})
    image[5, 5, 3] = 1.0                                      # one opaque pixel is something
    parts = shapely.get_parts(shape_geometry(image_cutout(image)))
    assert len(parts) == 2 and min(part.area for part in parts) >= 1.0
    assert specks(image[50:70, 50:70]) == (0, 0.0)


def test_map_by_triangles_maps_each_triangle_affinely_as_a_face_shows_its_uvs():
    """A parallelogram maps by one affine map; a quad with a corner moved maps each of its two
    triangles by its own, meeting on the diagonal, with its corners exact (one affine map fitted
    to the four corners missed them); a point outside follows the nearest triangle's map."""
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    halves = np.array([[0, 1, 2], [0, 2, 3]])
    affine = np.array([[2, 1, 3], [0, 0.5, -1], [0, 0, 1.0]])
    probes = np.random.default_rng(0).uniform(-0.2, 1.2, (50, 2))
    np.testing.assert_allclose(map_by_triangles(square, apply_affine(affine, square), halves, probes),
                               apply_affine(affine, probes), atol=1e-12)
    pinned = square + [[0, 0], [0, 0], [0.3, 0.2], [0, 0]]
    np.testing.assert_allclose(map_by_triangles(pinned, square, halves, pinned), square, atol=1e-12)
    diagonal = np.linspace(0, 1, 5)[:, None] * pinned[2]
    np.testing.assert_allclose(map_by_triangles(pinned, square, halves, diagonal),
                               np.linspace(0, 1, 5)[:, None] * [1.0, 1.0], atol=1e-12)
    # Under the first triangle's edge: its map, x + (-0.25) y and (1 / 1.2) y, carried on.
    below = map_by_triangles(pinned, square, halves, [[0.5, -0.1]])
    np.testing.assert_allclose(below, [[0.525, -0.1 / 1.2]], atol=1e-12)
    with pytest.raises(ValueError, match="one line"):
        map_by_triangles(np.array([[0, 0], [1, 1], [2, 2.0]]), np.zeros((3, 2)), [[0, 1, 2]], [[0, 0]])


def test_smallest_angles():
    from solver.rigging.outline import smallest_angles
    points = np.array([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2], [2, 0], [1, 1e-3], [0, 0]])
    angles = smallest_angles(points, [[0, 1, 2], [0, 3, 4], [0, 1, 5]])
    np.testing.assert_allclose(angles, [np.pi / 3, np.arctan(1e-3), 0.0], atol=1e-9)


def test_with_area_leaves_out_rings_on_one_line():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    line = np.array([[2, 0], [3, 0], [4, 0]], dtype=float)
    kept = with_area([line, square, line[:2]])
    assert len(kept) == 1 and kept[0] is square


@pytest.mark.parametrize("height, budget", [(0.5, 50_000), (2.0, 50_000), (7.0, 50_000), (7.0, 100)])
def test_refine_level_cuts_a_fill_to_the_spacing_within_its_budget(height, budget):
    """A rectangle filled by two triangles spanning it (as a text's letter is): each level
    halves the fill's edges; it stops where the longest is no longer than the spacing, or where
    the fill would have more faces than its budget, or at the deformer's most."""
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, height], [0.0, height]])
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]])
    spacing, most = 0.02, 6
    level = refine_level(corners, edges, 2, spacing, most, budget)
    longest = np.hypot(1.0, height)
    assert 2 * 4 ** level <= budget and level <= most
    assert longest / 2 ** level <= spacing or 2 * 4 ** (level + 1) > budget or level == most
    assert level == 0 or longest / 2 ** (level - 1) > spacing  # no finer than needed
    assert refine_level(corners, edges, 0, spacing, most, budget) == 0  # edges alone (an unfilled curve)
