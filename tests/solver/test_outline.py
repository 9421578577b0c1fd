"""solver.outline: the paper's graph for an outline given a number of points."""

import numpy as np
import pytest

from solver import Deformer
from solver.outline import outline_graph, parts_graph, simplify_rings, spacing_for_count

from sample_shapes import disk


def test_spacing_for_count():
    spacing = spacing_for_count([disk(1.0, 256)], 100)
    assert spacing == pytest.approx(np.sqrt(np.pi / 100), rel=1e-3)


def test_outline_graph_of_a_dense_outline_has_about_count_points():
    side = np.linspace(0, 1, 400, endpoint=False)
    square = np.concatenate([np.stack([side, 0 * side], 1), np.stack([1 + 0 * side, side], 1),
                             np.stack([1 - side, 1 + 0 * side], 1), np.stack([0 * side, 1 - side], 1)])
    assert len(simplify_rings([square], 1e-3)[0]) == 4
    graph = outline_graph([square], 100)
    assert 100 < graph.n < 250


@pytest.mark.parametrize("seed", range(6))
def test_a_needle_hole_thinner_than_the_detail_kept_is_left_out(seed):
    """A closed spline whose points are on one line to float32 rounding, inside a disk: its
    needle of a hole made the triangulation refine without end (30,000-55,000 points, 6-16 s,
    for a count of 300). Holes and islands thinner than the detail kept go; a thin shape alone
    stays."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-0.5, 0.5, 2)
    direction = rng.uniform(-0.3, 0.3, 2)
    t = np.linspace(0.0, 1.0, 12)[:, None]
    needle = np.concatenate([start + t * direction, (start + t[::-1] * direction)[1:-1]])
    needle = needle + rng.normal(scale=1e-8, size=needle.shape)  # float32 rounding's width
    graph = outline_graph([disk(1.0, 60), needle], 300)
    assert graph.n < 600 and len(graph.boundary_loops) == 1
    sliver = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1e-4], [0.0, 1e-4]])
    assert len(simplify_rings([sliver], 0.01)) == 1


def test_parts_that_overlap_stay_apart():
    """Two parts drawn over each other (an arm across a body) make one graph of two islands at
    one spacing, about ``count`` interior points in all: dragging the arm's end moves the arm
    alone, and the body, without handles, stays at rest."""
    body = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [0.0, 2.0]])
    arm = np.array([[0.2, 1.0], [2.5, 1.0], [2.5, 1.4], [0.2, 1.4]])
    graph, part = parts_graph([[body], [arm]], 300)
    assert graph.components().max() == 1 and np.array_equal(np.unique(part), [0, 1])
    assert np.all(part[graph.edges[:, 0]] == part[graph.edges[:, 1]])
    assert 200 < len(graph.interior) < 450
    assert graph.area() == pytest.approx(2.0 + 2.3 * 0.4, rel=1e-9)
    lengths = np.linalg.norm(np.diff(graph.points[graph.edges], axis=1)[:, 0], axis=1)
    assert lengths.max() < 2.5 * graph.spacing
    tip = np.flatnonzero((part == 1) & (graph.points[:, 0] > 2.45))
    root = np.flatnonzero((part == 1) & (graph.points[:, 0] < 0.25))
    handles = np.concatenate([root, tip])
    targets = graph.points[handles].copy()
    targets[len(root):] += [-0.5, 1.0]
    positions = Deformer(graph, handles).solve(targets).positions
    np.testing.assert_array_equal(positions[part == 0], graph.points[part == 0])
    assert np.abs(positions[part == 1] - graph.points[part == 1]).max() > 0.5
