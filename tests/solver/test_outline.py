"""solver.outline: the paper's graph for an outline given a number of points."""

import numpy as np
import pytest

from solver.outline import outline_graph, simplify_rings, spacing_for_count

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
