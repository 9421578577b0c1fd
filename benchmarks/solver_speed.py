"""Speed of the solver, in the layout of the paper's Table 1, beside libigl's 2D ARAP.

Run: .venv/bin/python benchmarks/solver_speed.py [--large]

Both methods get the same triangles, the same handle vertices and the same targets in the same
run. libigl (dev-only, PyPI ``libigl``) runs ``arap_solve`` with 10 iterations, as a typical
interactive budget; ours runs to its default tolerance. "back-sub" is one solve with our
factor alone: the floor under any iteration of the paper's method.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import solver  # noqa: E402
from benchmarks.peers import fine_factor  # noqa: E402
from benchmarks.shapes import SHAPES, horse, standard_drag  # noqa: E402


def median_time(function, repeats):
    return median_times([function], repeats)[0]


def median_times(functions, repeats):
    """Median seconds of each function, timed in turns (one call of each per round), so that a
    busy spell on the machine slows all of them alike and their ratios hold."""
    times = [[] for _ in functions]
    for _ in range(repeats):
        for function, kept in zip(functions, times):
            start = time.perf_counter()
            function()
            kept.append(time.perf_counter() - start)
    return [float(np.median(kept)) for kept in times]


def libigl_arap(graph, handles, targets, iterations):
    import igl

    data = igl.ARAPData()
    data.max_iter = iterations
    vertices = np.ascontiguousarray(graph.points)
    faces = np.ascontiguousarray(graph.triangles, dtype=np.int64)
    b = np.ascontiguousarray(handles, dtype=np.int32)
    start = time.perf_counter()
    igl.arap_precomputation(vertices, faces, 2, b, data)
    precompute = time.perf_counter() - start
    solve = lambda: igl.arap_solve(np.ascontiguousarray(targets), data, vertices)
    return precompute, solve


def measure(name, rings, spacing, repeats):
    start = time.perf_counter()
    graph = solver.build_graph(rings, spacing=spacing)
    build = time.perf_counter() - start
    handles, targets = standard_drag(graph)
    start = time.perf_counter()
    deformer = solver.Deformer(graph, handles)
    precompute = time.perf_counter() - start
    pose = deformer.solve(targets)
    rhs = np.ones(2 * len(deformer.free))
    back = median_time(lambda: fine_factor(deformer).solve(rhs), max(repeats, 20))
    igl_pre, igl_solve = libigl_arap(graph, handles, targets, 10)
    igl_solve()
    ours, igl_time = median_times([lambda: deformer.solve(targets), igl_solve], repeats)
    return {
        "shape": name, "boundary": len(graph.boundary), "interior": len(graph.interior),
        "graph ms": build * 1e3, "precompute ms": precompute * 1e3,
        "iterations": pose.iterations, "newton": pose.factorizations,
        "per iteration ms": ours * 1e3 / max(pose.iterations, 1), "solve ms": ours * 1e3,
        "back-sub ms": back * 1e3, "libigl pre ms": igl_pre * 1e3, "libigl 10 it ms": igl_time * 1e3,
        "ratio": ours / igl_time,
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--large", action="store_true", help="add a 50,000-point horse")
    parser.add_argument("--repeats", type=int, default=31)
    args = parser.parse_args(argv)

    cases = [(name, make(), None) for name, make in SHAPES.items()]
    horse_rings = horse()
    area = solver.shapes.shape_geometry(horse_rings).area
    cases.append(("horse 5k", horse_rings, np.sqrt(area / 4300)))
    if args.large:
        cases.append(("horse 50k", horse_rings, np.sqrt(area / 46000)))
    rows = []
    for name, rings, spacing in cases:
        rows.append(measure(name, rings, spacing, args.repeats if "k" not in name[-2:] else 5))
        print(f"measured {name}", file=sys.stderr, flush=True)

    columns = list(rows[0])
    print(f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, numpy {np.__version__}")
    print()
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))
    for row in rows:
        cells = [f"{v:.3g}" if isinstance(v, float) else str(v) for v in row.values()]
        print("| " + " | ".join(cells) + " |")
    print()
    print("ratio = our converged solve / libigl's 10 ARAP iterations (< 1 means we are faster).")


if __name__ == "__main__":
    main()
