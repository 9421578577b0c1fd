"""Bitmaps to rings, and points bound to the graph."""

import numpy as np
import pytest

import solver
from sample_shapes import disk, region
from solver.shapes import signed_area


def annulus_image(size=200, outer=80, inner=35):
    y, x = np.mgrid[0:size, 0:size] + 0.5
    r = np.hypot(x - size / 2, y - size / 2)
    return (r <= outer) & (r >= inner)


def test_annulus_traces_to_an_outer_ring_and_a_hole():
    rings = solver.trace_silhouette(annulus_image())
    assert len(rings) == 2
    areas = sorted(signed_area(r) for r in rings)
    assert areas[0] < 0 < areas[1]  # hole clockwise, outline counter-clockwise
    assert areas[1] == pytest.approx(np.pi * 80 ** 2, rel=0.01)
    assert -areas[0] == pytest.approx(np.pi * 35 ** 2, rel=0.02)
    centre = np.mean(np.concatenate(rings), axis=0)
    assert np.allclose(centre, [100, 100], atol=0.5)  # pixel (r, c) covers [c, c+1] x [r, r+1]


@pytest.mark.parametrize("kind", ["bool", "float", "uint8", "rgba", "la"])
def test_image_kinds_agree(kind):
    mask = annulus_image()
    image = {"bool": mask, "float": mask.astype(float), "uint8": (mask * 255).astype(np.uint8),
             "rgba": np.dstack([np.zeros(mask.shape + (3,)), mask.astype(float)]),
             "la": np.dstack([np.ones(mask.shape), mask.astype(float)])}[kind]
    area = sum(signed_area(r) for r in solver.trace_silhouette(image))
    assert area == pytest.approx(np.pi * (80 ** 2 - 35 ** 2), rel=0.02)


def test_vertex_budget_and_specks(horse_rings):
    from skimage.data import horse

    image = horse()[::-1] == 0
    noisy = image.copy()
    noisy[5, 5] = noisy[300, 20] = True  # two one-pixel specks
    assert len(solver.trace_silhouette(noisy)) == len(solver.trace_silhouette(image))
    budget = solver.trace_silhouette(image, max_vertices=120)
    assert sum(len(r) for r in budget) <= 120
    full = solver.trace_silhouette(image, tolerance=0.0)
    assert sum(len(r) for r in full) > sum(len(r) for r in budget)


@pytest.mark.parametrize("image, message", [
    (np.zeros((50, 50)), "nothing to trace"),
    (np.zeros((50, 50, 3)), "alpha"),
    (np.zeros(5), "shape"),
    (np.full((10, 10), np.nan), "NaN"),
])
def test_bad_images_are_refused(image, message):
    with pytest.raises(ValueError, match=message):
        solver.trace_silhouette(image)


def test_binding_reproduces_rest_and_follows(horse_graph, horse_drag):
    rng = np.random.default_rng(1)
    low, high = horse_graph.points.min(0) - 15, horse_graph.points.max(0) + 15
    points = rng.uniform(low, high, (3000, 2))
    binding = solver.bind(horse_graph, points)
    assert np.abs(binding.apply(horse_graph.points) - points).max() <= 1e-12 * horse_graph.size
    assert np.allclose(binding.weights.sum(axis=1), 1.0)
    # A rigid motion of the graph moves every bound point, inside or outside, rigidly.
    c, s = np.cos(1.1), np.sin(1.1)
    turn = np.array([[c, -s], [s, c]])
    moved = binding.apply(horse_graph.points @ turn.T + [3.0, 4.0])
    assert np.abs(moved - (points @ turn.T + [3.0, 4.0])).max() <= 1e-9 * horse_graph.size


def test_bound_points_follow_continuously_inside_outside_and_across_the_boundary(horse_graph, horse_drag):
    """No bound point jumps: nearby rest points stay nearby after a drag, everywhere, also
    between the legs (where the nearest boundary switches from one leg to the other) and across
    the boundary. Following only the nearest triangle, points there moved by up to 15% of the
    size for a rest offset of 1e-6 of it."""
    graph = horse_graph
    handles, targets, _ = horse_drag
    pose = solver.Deformer(graph, handles).solve(targets).positions
    rng = np.random.default_rng(2)
    low, high = graph.points.min(0) - 15, graph.points.max(0) + 15
    points = rng.uniform(low, high, (4000, 2))
    step = 1e-6 * graph.size
    shifted = points + step * rng.normal(size=points.shape)
    apart = np.linalg.norm(solver.bind(graph, points).apply(pose) - solver.bind(graph, shifted).apply(pose), axis=1)
    assert apart.max() < 20 * np.linalg.norm(points - shifted, axis=1).max()
    # Just outside and just inside the middle of every boundary edge land together.
    here = np.concatenate(graph.boundary_loops)
    after = np.concatenate([np.roll(loop, -1) for loop in graph.boundary_loops])
    middle = 0.5 * (graph.points[here] + graph.points[after])
    along = graph.points[after] - graph.points[here]
    outward = np.stack([along[:, 1], -along[:, 0]], axis=1) / np.linalg.norm(along, axis=1)[:, None]
    outside = solver.bind(graph, middle + step * outward).apply(pose)
    inside = solver.bind(graph, middle - step * outward).apply(pose)
    assert np.linalg.norm(outside - inside, axis=1).max() < 20 * 2 * step


def test_bad_points_are_refused(horse_graph):
    with pytest.raises(ValueError, match="non-finite"):
        solver.bind(horse_graph, [[0.0, np.nan]])
    with pytest.raises(ValueError, match="shape"):
        solver.bind(horse_graph, np.zeros((3, 3)))


@pytest.mark.parametrize("convert", [lambda m: m.astype(int), lambda m: m.astype(np.uint8), lambda m: m.astype(np.int32),
                                     lambda m: m.astype(int).tolist()])
def test_a_mask_of_zeros_and_ones_traces_whatever_its_integer_type(convert):
    """An int64, int32 or uint8 mask of 0 and 1 (or a list of them) was divided by its type's
    largest value and found 'fully transparent'."""
    mask = np.zeros((20, 30), bool)
    mask[5:15, 5:25] = True
    expected = solver.trace_silhouette(mask)
    got = solver.trace_silhouette(convert(mask))
    assert len(got) == len(expected) and np.allclose(got[0], expected[0])


def test_an_integer_image_without_a_full_scale_is_refused_by_name():
    with pytest.raises(ValueError, match="integer image of type int64 .*no full scale"):
        solver.trace_silhouette(np.full((8, 8), 255, dtype=np.int64))


def test_pixels_at_the_level_are_traced_and_the_images_edge_is_traced_on_it():
    """"At or above level": a picture all of alpha 255 traced at 1, or pixels of 0.5 at 0.5,
    had nothing traced (QA). A shape touching the image's edge was traced a sixth of a pixel
    inside it: it meets the edge as it meets an empty pixel inside, or runs along it."""
    from solver.shapes import shape_geometry

    rgba = np.zeros((10, 10, 4), np.uint8)
    rgba[2:8, 2:8, 3] = 255
    half = np.where(rgba[..., 3] > 0, 0.5, 0.0)
    for image, level in ((rgba, 1.0), (half, 0.5)):
        assert shape_geometry(solver.trace_silhouette(image, level=level, tolerance=0)).area > 20
    full = np.ones((10, 30), bool)
    corner = np.zeros((10, 30), bool)
    corner[:4, :6] = True
    for mask in (full, corner):
        alone = shape_geometry(solver.trace_silhouette(mask, tolerance=0))
        padded = shape_geometry([ring - 1 for ring in solver.trace_silhouette(np.pad(mask, 1), tolerance=0)])
        assert alone.symmetric_difference(padded).area < 1e-9


@pytest.mark.parametrize("level", [1.0 / 255.0, 0.1, 0.5, 0.9])
def test_a_trace_stays_in_the_picture_at_any_level(level):
    """Between an edge pixel and the border the contour crosses a low level half a pixel out
    (QA: up to 0.5 pixel outside the image at 1/255)."""
    import shapely

    from solver.shapes import shape_geometry

    image = np.zeros((20, 30))
    image[5:15, :10], image[:3, 20:] = 1.0, 0.95
    traced = shape_geometry(solver.trace_silhouette(image, level=level, tolerance=0))
    assert shapely.box(0, 0, 30, 20).contains(traced)
    assert traced.area >= 0.75 * (100 + 30)  # the pixels, less what a high level cuts off their outline
