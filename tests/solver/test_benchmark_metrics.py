"""Sanity of the quality measures in benchmarks/metrics.py (no bpy, no solver internals)."""

import numpy as np
import pytest

import solver
from benchmarks import metrics
from sample_shapes import glyph_rings


@pytest.fixture(scope="module")
def glyph_graph():
    return solver.build_graph(glyph_rings("B"))


def turn(points, angle, shift=(0.0, 0.0)):
    c, s = np.cos(angle), np.sin(angle)
    return points @ np.array([[c, -s], [s, c]]).T + np.asarray(shift)


def all_measures(graph, deformed, handles=None):
    handles = np.arange(5) if handles is None else handles
    return metrics.measure(graph.points, deformed, graph.triangles, graph.boundary_loops,
                           handles, deformed[handles])


def test_identity_is_perfect(glyph_graph):
    m = all_measures(glyph_graph, glyph_graph.points.copy())
    assert m["area ratio"] == pytest.approx(1.0, abs=1e-12)
    assert m["ARAP / area"] == pytest.approx(0.0, abs=1e-12)
    assert m["local area spread"] == pytest.approx(0.0, abs=1e-12)
    assert m["boundary Laplacian"] == pytest.approx(0.0, abs=1e-12)
    assert m["flips"] == 0
    assert m["handle error"] == 0.0


def test_rigid_motion_costs_nothing(glyph_graph):
    moved = turn(glyph_graph.points, 2.5, (3.0, -7.0))
    m = all_measures(glyph_graph, moved)
    assert m["area ratio"] == pytest.approx(1.0, abs=1e-10)
    assert m["ARAP / area"] == pytest.approx(0.0, abs=1e-10)
    assert m["boundary Laplacian"] == pytest.approx(0.0, abs=1e-10)
    assert m["local area spread"] == pytest.approx(0.0, abs=1e-10)
    assert m["flips"] == 0


def test_uniform_scale_has_the_closed_form_values(glyph_graph):
    s = 1.5
    m = all_measures(glyph_graph, s * turn(glyph_graph.points, 0.3))
    assert m["area ratio"] == pytest.approx(s * s)
    # ||s R - R||_F^2 = 2 (s - 1)^2 for every triangle.
    assert m["ARAP / area"] == pytest.approx(2 * (s - 1) ** 2)
    # Every Laplacian scales by s: |s d - d| / rest edge, averaged, still > 0.
    assert m["boundary Laplacian"] > 0
    assert m["local area spread"] == pytest.approx(0.0, abs=1e-10)


def test_mirror_flips_every_triangle_and_stretch_is_seen(glyph_graph):
    mirrored = glyph_graph.points * [-1.0, 1.0]
    assert metrics.flipped(glyph_graph.points, mirrored, glyph_graph.triangles) == len(glyph_graph.triangles)
    stretched = glyph_graph.points * [1.0, 2.0]
    gradients = metrics.deformation_gradients(glyph_graph.points, stretched, glyph_graph.triangles)
    assert np.allclose(gradients, np.diag([1.0, 2.0]))
    # Closest rotation to diag(1, 2) is the identity: energy (2 - 1)^2 = 1.
    assert metrics.arap_energy_per_area(glyph_graph.points, stretched, glyph_graph.triangles) == pytest.approx(1.0)
    assert metrics.area_ratio(glyph_graph.points, stretched, glyph_graph.triangles) == pytest.approx(2.0)


def test_handle_error_is_relative_to_the_drag(glyph_graph):
    rest = glyph_graph.points
    handles = np.array([0, 1])
    targets = rest[handles] + [[0.0, 0.0], [2.0, 0.0]]
    deformed = rest.copy()
    deformed[1] += [1.5, 0.0]  # misses by 0.5 of a drag of 2
    assert metrics.handle_error(rest, deformed, handles, targets) == pytest.approx(0.25)


def test_boundary_laplacian_sees_a_local_bump_but_not_a_turn():
    angle = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    ring = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    loops = [np.arange(40)]
    assert metrics.boundary_laplacian_change(ring, turn(ring, 1.0), loops) == pytest.approx(0.0, abs=1e-12)
    bumped = ring.copy()
    bumped[7] *= 1.2
    assert metrics.boundary_laplacian_change(ring, bumped, loops) > 0.01
