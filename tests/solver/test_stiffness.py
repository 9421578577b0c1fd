"""Per-point stiffness (starch): a stiffened region bends less; stiffness 1 is the paper's energy."""

import numpy as np
import pytest

import solver


def bar():
    """A long bar (8 x 1) with its handles at both ends."""
    rings = [np.array([[0.0, 0.0], [8.0, 0.0], [8.0, 1.0], [0.0, 1.0]])]
    graph = solver.build_graph(rings, spacing=0.25)
    left = np.flatnonzero(graph.points[:, 0] < 0.4)
    right = np.flatnonzero(graph.points[:, 0] > 7.6)
    return graph, left, right


def bend(graph, left, right, stiffness=None):
    """Turn the right end a quarter turn up over the left: the bar curls."""
    handles = np.concatenate([left, right])
    angle = np.pi / 2
    turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    pivot = np.array([4.0, 0.5])
    targets = np.concatenate([graph.points[left],
                              (graph.points[right] - [8.0, 0.5]) @ turn.T + pivot + [1.5, 2.5]])
    deformer = solver.Deformer(graph, handles, prevent_flips=True, stiffness=stiffness)
    return deformer.solve(targets, max_iterations=200).positions


def turning(graph, positions, region):
    """How much the bar's centre line turns across ``region`` (a mask over the points): the
    angle between the best-fit directions of its first and last thirds."""
    xs = graph.points[region, 0]
    lo, hi = np.quantile(xs, [1 / 3, 2 / 3])
    def direction(mask):
        pts = positions[region][mask]
        centred = pts - pts.mean(axis=0)
        axis = np.linalg.svd(centred, full_matrices=False)[2][0]
        return axis * np.sign(axis @ (positions[region][xs > hi].mean(axis=0) - positions[region][xs < lo].mean(axis=0)))
    a, b = direction(xs < lo), direction(xs > hi)
    return float(np.arccos(np.clip(a @ b, -1.0, 1.0)))


def test_stiffness_one_everywhere_is_the_plain_energy():
    graph, left, right = bar()
    np.testing.assert_allclose(bend(graph, left, right, np.ones(graph.n)), bend(graph, left, right), atol=1e-9)


def test_a_starched_middle_bends_less_than_half():
    graph, left, right = bar()
    middle = np.abs(graph.points[:, 0] - 4.0) < 1.5
    stiffness = np.where(middle, 30.0, 1.0)
    plain = turning(graph, bend(graph, left, right), middle)
    starched = turning(graph, bend(graph, left, right, stiffness), middle)
    assert plain > 0.3  # the plain bar curls through the middle
    assert starched < 0.5 * plain


@pytest.mark.parametrize("bad", [np.zeros(5), -1.0, np.nan])
def test_bad_stiffness_is_refused(bad):
    graph, left, right = bar()
    values = np.full(graph.n, bad) if np.ndim(bad) == 0 else bad
    with pytest.raises(ValueError, match="stiffness"):
        solver.Deformer(graph, np.concatenate([left, right]), stiffness=values)


def folded(graph, positions):
    return int((solver.triangulate.triangle_cross(positions, graph.triangles)
                * solver.triangulate.triangle_cross(graph.points, graph.triangles) < 0).sum())


def test_a_stiffness_the_same_everywhere_changes_no_pose_with_the_fold_penalty(bar_pushed_together):
    """It scales the whole energy; the fold penalty was left unscaled, so it moved the pose."""
    graph, handles, targets = bar_pushed_together
    plain = solver.Deformer(graph, handles, prevent_flips=True).solve(targets, max_iterations=300).positions
    starched = solver.Deformer(graph, handles, prevent_flips=True, stiffness=np.full(graph.n, 10.0)).solve(
        targets, max_iterations=300).positions
    assert np.abs(plain - starched).max() <= 1e-9 * graph.size


@pytest.mark.parametrize("amount", [10.0, 100.0, 1000.0])
def test_starch_folds_no_triangle_the_pose_without_it_keeps_open(bar_pushed_together, amount):
    """A bar pushed to a quarter of its length buckles without folding; starching its middle
    folded 1, 2 and 9 triangles (the stiffer energy overpowered the penalty there)."""
    graph, handles, targets = bar_pushed_together
    plain = solver.Deformer(graph, handles, prevent_flips=True).solve(targets, max_iterations=200).positions
    assert folded(graph, plain) == 0
    stiffness = np.ones(graph.n)
    stiffness[np.abs(graph.points[:, 0] - 4.0) < 2.0] = amount
    starched = solver.Deformer(graph, handles, prevent_flips=True, stiffness=stiffness).solve(
        targets, max_iterations=200).positions
    assert folded(graph, starched) == 0


@pytest.fixture
def bar_pushed_together():
    graph = solver.build_graph([np.array([[0.0, 0.0], [8.0, 0.0], [8.0, 1.0], [0.0, 1.0]])], spacing=0.2)
    left, right = np.flatnonzero(graph.points[:, 0] < 0.3), np.flatnonzero(graph.points[:, 0] > 7.7)
    targets = np.concatenate([graph.points[left], graph.points[right] - [6.0, 0.0]])
    return graph, np.concatenate([left, right]), targets
