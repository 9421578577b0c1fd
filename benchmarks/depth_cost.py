"""What depth for overlaps costs per update, beside the solve it follows.

Run: .venv/bin/python benchmarks/depth_cost.py [--repeats 200]

On the random-drag benchmark's shapes at the paper's size and at about 5,000 points (seed 2006,
each shape's first drag), times in turns, median: the solve (the add-on's default deformer, 15
iterations), and what the add-on adds after it every update (``solver.rigging.depth``): the
automatic score, where the pose overlaps itself (``automatic_reach``: the automatic order applies
only there) and the heights with four overlap pins' amounts. The pins' reach (a shortest-
path search per pin along the graph) is computed once per handle set, when the rig is built,
and is timed on its own.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks import random_drags  # noqa: E402
from benchmarks.solver_speed import median_times  # noqa: E402
from solver.rigging import depth  # noqa: E402

PINS = 4


def median_ms(functions, repeats):
    """Median milliseconds of each function, timed in turns (solver_speed.median_times)."""
    return [1000.0 * t for t in median_times(functions, repeats)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args(argv)
    print("| size | shape | graph points | solve (ms) | depth per update (ms) | share of the solve "
          "| pins' reach, once per rig (ms) |")
    print("|---|---|---|---|---|---|---|")
    for size in ("paper", "5k"):
        seen = set()
        for case in random_drags.cases(2006, size, drags=1):
            if case.shape in seen:
                continue
            seen.add(case.shape)
            graph = case.graph
            deformer = random_drags.default_deformer(graph, case.handles, prevent_flips=True)
            posed = deformer.solve(case.targets, max_iterations=15).positions
            rng = np.random.default_rng(0)
            pins = rng.choice(graph.n, PINS, replace=False)
            extents = np.full(PINS, 0.25 * graph.size)
            reach = depth.pin_weights(graph.points, graph.edges, pins, extents)
            amounts = np.array([1.0, -1.0, 0.5, 2.0])

            lengths = depth.edge_lengths(graph.points, graph.edges)  # once per rig

            def per_update():
                score = depth.moved_score(graph.points, posed, graph.size) * \
                    depth.automatic_reach(posed, graph.triangles, lengths, graph.size)
                return depth.heights(score, graph.size, amounts, reach)

            solve, update = median_ms([lambda: deformer.solve(case.targets, max_iterations=15), per_update],
                                      max(3, args.repeats // 20))
            update = median_ms([per_update], args.repeats)[0]
            once = median_ms([lambda: depth.pin_weights(graph.points, graph.edges, pins, extents)],
                             max(3, args.repeats // 10))[0]
            print(f"| {size} | {case.shape} | {graph.n} | {solve:.2f} | {update:.3f} | {update / solve:.1%} "
                  f"| {once:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
