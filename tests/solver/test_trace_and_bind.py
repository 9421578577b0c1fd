"""Bitmaps to rings, and points bound to the graph."""

import numpy as np
import pytest

import solver
from conftest import disk, region
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
    # Bound points follow a deformation smoothly: near points stay near.
    handles, targets, _ = horse_drag
    pose = solver.Deformer(horse_graph, handles).solve(targets).positions
    close = points + 0.01
    spread = np.linalg.norm(binding.apply(pose) - solver.bind(horse_graph, close).apply(pose), axis=1)
    assert np.percentile(spread, 99) < 0.1


def test_bad_points_are_refused(horse_graph):
    with pytest.raises(ValueError, match="non-finite"):
        solver.bind(horse_graph, [[0.0, np.nan]])
    with pytest.raises(ValueError, match="shape"):
        solver.bind(horse_graph, np.zeros((3, 3)))
