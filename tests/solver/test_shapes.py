"""Rings in: orientation, nesting, repair, and clear refusals."""

import numpy as np
import pytest

import solver
from solver.shapes import shape_geometry, signed_area
from sample_shapes import disk, glyph_rings

SQUARE = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], dtype=float)
HOLE = np.array([[1, 1], [3, 1], [3, 3], [1, 3]], dtype=float)


@pytest.mark.parametrize("copy", ["same", "reversed", "started elsewhere"])
def test_a_ring_repeated_on_itself_counts_once(copy):
    """A closed spline duplicated in place (Shift+D, Esc): by nesting each copy was a hole in
    the other and the shape was refused ("the rings enclose no area"). A ring repeated exactly,
    in either direction and from any point, is one outline, around a hole as well."""
    again = {"same": SQUARE, "reversed": SQUARE[::-1], "started elsewhere": np.roll(SQUARE, 2, axis=0)}[copy]
    assert shape_geometry([SQUARE, again]).area == pytest.approx(16.0)
    assert shape_geometry([SQUARE, HOLE, again, HOLE[::-1]]).area == pytest.approx(12.0)


@pytest.mark.parametrize("flip_outer, flip_hole", [(False, False), (True, False), (False, True), (True, True)])
def test_orientation_and_nesting_are_worked_out(flip_outer, flip_hole):
    outer = SQUARE[::-1] if flip_outer else SQUARE
    hole = HOLE[::-1] if flip_hole else HOLE
    graph = solver.build_graph([hole, outer])  # the hole first: order must not matter
    areas = [signed_area(graph.points[loop]) for loop in graph.boundary_loops]
    assert sorted(np.sign(areas)) == [-1, 1]
    assert graph.area() == pytest.approx(12.0, rel=1e-12)


def test_island_inside_a_hole_is_material():
    island = disk(0.4, 16, centre=(2, 2))
    assert shape_geometry([SQUARE, HOLE, island]).area == pytest.approx(12.0 + abs(signed_area(island)), rel=1e-9)
    graph = solver.build_graph([SQUARE, HOLE, island])
    assert len(graph.boundary_loops) == 3
    assert graph.area() == pytest.approx(12.0 + abs(signed_area(island)), rel=1e-9)


def test_glyphs_with_holes_and_islands():
    rings = glyph_rings("Bi")  # B: one island, two holes; i: two islands
    graph = solver.build_graph(rings)
    assert len(graph.boundary_loops) == 5
    assert len(np.unique(graph.components())) == 3
    assert graph.area() == pytest.approx(shape_geometry(rings).area, rel=1e-9)


def test_duplicates_and_collinear_runs_are_normal_input():
    dense = np.concatenate([np.linspace([0, 0], [4, 0], 40, endpoint=False),
                            np.linspace([4, 0], [4, 1], 10, endpoint=False),
                            np.linspace([4, 1], [0, 1], 40, endpoint=False),
                            np.linspace([0, 1], [0, 0], 10, endpoint=False)])
    repeated = np.repeat(dense, 2, axis=0)           # every point twice
    repeated = np.concatenate([repeated, dense[:1]])  # and the ring closed explicitly
    graph = solver.build_graph([repeated])
    assert graph.area() == pytest.approx(4.0, rel=1e-12)
    assert len(graph.boundary) >= 100


def test_figure_eight_is_repaired_into_two_lobes():
    eight = np.array([[0, 0], [2, 2], [2, 0], [0, 2]], dtype=float)  # crosses itself once
    geometry = shape_geometry([eight])
    assert geometry.is_valid and geometry.area > 0
    graph = solver.build_graph([eight])
    assert len(graph.boundary_loops) == 2
    assert graph.area() == pytest.approx(2.0, rel=1e-4)  # the pinch is pulled apart by 1e-6


@pytest.mark.parametrize("rings, message", [
    ([], "no rings"),
    ([np.array([[0, 0], [1, 0], [0, 0]], float)], "fewer than 3 distinct points"),
    ([np.array([[0, 0], [1, 0], [np.nan, 1]], float)], "non-finite"),
    ([np.array([[0, 0], [1, 0], [np.inf, 1]], float)], "non-finite"),
    ([np.array([[0, 0], [1, 1], [2, 2], [3, 3]], float)], "zero area"),
    ([np.zeros((4, 3))], r"\(k, 2\)"),
    ([np.array([[0, 0], [2, 0], [1, 0], [3, 0], [1, 1e-300]], float)], "ring 0"),
])
def test_malformed_input_is_refused_by_name(rings, message):
    with pytest.raises(ValueError, match=message):
        solver.build_graph(rings)


def test_bad_spacing_is_refused():
    with pytest.raises(ValueError, match="spacing"):
        solver.build_graph([SQUARE], spacing=-1)
