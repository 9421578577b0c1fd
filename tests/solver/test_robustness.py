"""Varied valid shapes through the whole pipeline: build, solve with each option, bind.

A seeded sample of what fuzzing found hard: spiky and smooth stars, thin slanted bars, rings,
many holes, islands (one inside a hole), and shapes a millionth of their offset in size or at
very small and large scales. Each gets one to three handle regions, a moderate drag and a drag a
hundred times its size. A valid shape is never refused; poses are finite, handles exact, the
energy never rises, the area is kept where asked, and bound points reproduce their rest.
"""

import zlib

import numpy as np
import pytest

import solver


def _star(rng, count, spiky):
    angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    if spiky:
        radius = np.where(np.arange(count) % 2 == 0, 1.0, rng.uniform(0.05, 0.5)) * rng.uniform(0.8, 1.2, count)
    else:
        radius = 1.0 + sum(rng.uniform(-0.25, 0.25) / k * np.cos(k * angle + rng.uniform(0, 6)) for k in range(1, 6))
    return [np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)]


def _circle(count, radius=1.0, centre=(0.0, 0.0)):
    angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    return np.stack([centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle)], axis=1)


def _bar(rng, aspect):
    c, s = np.cos(rng.uniform(0, np.pi)), np.sin(rng.uniform(0, np.pi))
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0 / aspect], [0.0, 1.0 / aspect]])
    return [corners @ np.array([[c, s], [-s, c]])]


def _holes(rng):
    holes = [_circle(int(rng.integers(3, 20)), 0.6, centre) for centre in
             [(2.0, 2.0), (5.0, 2.5), (8.0, 2.0), (3.0, 6.0), (7.0, 7.0)]]
    return [np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])] + holes


def _shapes():
    rng = np.random.default_rng(20261123)
    shapes = {f"spiky star {n}": _star(rng, n, True) for n in (6, 40, 150)}
    shapes.update({f"smooth star {n}": _star(rng, n, False) for n in (5, 60)})
    shapes.update({f"bar 1:{a}": _bar(rng, a) for a in (30, 200)})
    shapes["thin ring"] = [_circle(64), _circle(64, 0.97)]
    shapes["five holes"] = _holes(rng)
    shapes["three islands"] = [_circle(24, 0.6, (3.0 * i, 0.5 * i)) for i in range(3)]
    shapes["island in a hole"] = [_circle(48, 2.0), _circle(40, 1.2), _circle(24, 0.5)]
    shapes["collinear runs"] = [np.repeat(np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 1.0], [0.0, 1.0]]), 3, axis=0)]
    for name, scale, offset in [("spiky star 6", 1.0, (1e6, -7e5)), ("smooth star 5", 1e-3, (1e3, 0.0)),
                                ("five holes", 1e4, (0.0, 0.0)), ("three islands", 1.0, (-4e5, 2e5))]:
        shapes[f"{name} x{scale:g} at {offset[0]:g}"] = [ring * scale + offset for ring in shapes[name]]
    return shapes


SHAPES = _shapes()


def _drags(graph, rng):
    """One to three handle regions (the first pinned), moved moderately and then 100x the size."""
    size = graph.size
    centres = graph.points[rng.choice(graph.n, int(rng.integers(1, 4)), replace=False)]
    taken = np.zeros(graph.n, dtype=bool)
    regions = []
    for centre in centres:
        inside = np.flatnonzero((np.linalg.norm(graph.points - centre, axis=1) < 0.06 * size) & ~taken)
        if len(inside):
            taken[inside] = True
            regions.append(inside)
    handles = np.concatenate(regions)
    for reach in (0.2, 100.0):
        targets = graph.points[handles].copy()
        start = len(regions[0]) if len(regions) > 1 else 0
        angle = rng.normal(0.0, 0.5)
        turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        pivot = graph.points[handles[start:]].mean(axis=0) if start < len(handles) else 0.0
        targets[start:] = (targets[start:] - pivot) @ turn.T + pivot + rng.normal(0.0, reach, 2) * size
        yield reach, handles, targets


@pytest.mark.parametrize("name", list(SHAPES))
def test_valid_shapes_build_solve_and_bind(name):
    rings = SHAPES[name]
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    graph = solver.build_graph(rings)
    assert graph.area() == pytest.approx(solver.shapes.shape_geometry(rings).area, rel=1e-6)
    size = graph.size
    for reach, handles, targets in _drags(graph, rng):
        for options in ({}, {"preserve_area": True}, {"prevent_flips": True}):
            try:
                pose = solver.Deformer(graph, handles, **options).solve(targets)
            except ValueError as error:  # the one refusal a valid shape may meet, by design
                assert options and "island without handles" in str(error)
                continue
            assert np.all(np.isfinite(pose.positions))
            assert np.abs(pose.positions[handles] - targets).max() <= 1e-9 * size * max(1.0, reach)
            assert np.all(np.diff(pose.energies) <= 1e-12 * max(pose.energies, default=0.0))
            if options.get("preserve_area"):
                # float64 limit: a pose 100 times the size across, a million sizes from the
                # origin, holds its coordinates to 1e-10 of the size, its area to about 1e-9.
                far = np.abs(graph.points).max() > 1e5 * size
                assert abs(graph.area(pose.positions) / graph.area() - 1.0) <= (1e-8 if far else 1e-9)
    low, high = graph.points.min(axis=0), graph.points.max(axis=0)
    points = rng.uniform(low - 0.2 * (high - low), high + 0.2 * (high - low), (300, 2))
    binding = solver.bind(graph, points)
    # Outside a needle-spiked star the blended maps extrapolate thin triangles: weights in the
    # hundreds multiply the rounding of coordinates far from the origin.
    rounding = 1e-12 * size + 1e-13 * np.abs(graph.points).max()
    assert np.abs(binding.apply(graph.points) - points).max() <= rounding
    assert np.all(np.isfinite(binding.apply(pose.positions)))


def test_a_shape_too_thin_to_triangulate_is_refused_by_name():
    """Qhull's own error (a RuntimeError with a traceback in Blender's console) becomes a
    ValueError saying what is wrong: the coarse copy a solve may start from is then skipped."""
    from solver.triangulate import filtered_delaunay
    import shapely

    points = np.column_stack([np.linspace(0.0, 1.0, 20), np.zeros(20)])
    points[::2, 1] = 1e-17
    with pytest.raises(ValueError, match="too thin to triangulate"):
        filtered_delaunay(points, shapely.box(0.0, 0.0, 1.0, 1e-17))


def test_a_solve_that_overflows_says_so_instead_of_returning_nan():
    """Targets 1e90-1e150 shape sizes apart gave positions all NaN and no error (QA). Any
    scale either solves to finite positions or raises FloatingPointError."""
    import warnings

    graph = solver.build_graph([np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)])
    deformer = solver.Deformer(graph, [0, 10, 20])
    raised = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for exponent in range(20, 161, 10):
            try:
                solution = deformer.solve(graph.points[[0, 10, 20]] * 10.0 ** exponent)
            except FloatingPointError:
                raised += 1
                continue
            assert np.all(np.isfinite(solution.positions)), exponent
    assert raised > 0  # the scales that overflowed before still do, and say so
