# SPDX-License-Identifier: GPL-3.0-or-later
"""Does adding a handle at a point of a posed shape leave the shape where it is? (issue 17, item 7)

Run: .venv/bin/python benchmarks/add_handle.py [--seed N] [--trials N] [--shapes NAME,...] [--every-start]

For each trial a shape at the paper's size gets one of ``random_drags``' random drags and is
solved as the add-on solves it (fold penalty on, default budget); then one more handle is added
at a random free point, with the point's posed position as its target, and the drag is solved
again. The posed shape still satisfies every handle, so ideally nothing moves. Printed: the
share of trials whose shape moved more than ``MOVED`` of its size, split by whether the new pose
has more energy (the solve fell into a worse minimum than the pose it had) or less (the first
solve had stopped in a worse minimum than one the second start found), and the median and
worst move.

``--every-start`` solves from each of the deformer's start candidates (the as-similar-as-possible
pose and the solved coarse copy's) and keeps the lowest final energy, instead of solving only
from the start of lower energy: twice the cost, measured here for comparison.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import solver  # noqa: E402
from benchmarks import random_drags  # noqa: E402

MOVED = 0.035  # of the shape's size: the threshold
GRID = "grid"  # a 2 x 1 rectangle, the issue's case, besides random_drags' shapes


def _rings(shape):
    if shape == GRID:
        return [np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])]
    return random_drags.SHAPES[shape]()


def _final_energy(solution):
    return float(solution.energies[-1]) if solution.energies else float("inf")


def solve(deformer, targets, every_start=False):
    """The add-on's solve, or with ``every_start`` the best of a solve from each start."""
    if not every_start:
        return deformer.solve(targets)
    starts = deformer._start_candidates(np.asarray(targets, dtype=np.float64), None)
    return min((deformer.solve(targets, initial=start) for start in starts), key=_final_energy)


def trial(graph, geometry, rng, every_start=False):
    """(move over size, energy before, energy after) for one drag and one added handle."""
    centres, radii, motions, _ = random_drags.random_drag(rng, geometry)
    handles, targets, _ = random_drags.place_drag(graph, centres, radii, motions)
    posed = solve(solver.Deformer(graph, handles, prevent_flips=True), targets, every_start)
    extra = rng.choice(np.setdiff1d(np.arange(graph.n), handles))
    more = solver.Deformer(graph, np.append(handles, extra), prevent_flips=True)
    again = solve(more, np.vstack([targets, posed.positions[extra]]), every_start)
    move = float(np.linalg.norm(again.positions - posed.positions, axis=1).max() / graph.size)
    return move, _final_energy(posed), _final_energy(again)


def run(seed, trials, shapes, every_start=False):
    """Rows of (shape, move, energy before, energy after)."""
    rows = []
    for shape in shapes:
        rings = _rings(shape)
        geometry = solver.shapes.shape_geometry(rings)
        graph = random_drags.sized_graph(rings, "paper")
        for k in range(trials):
            rng = np.random.default_rng([seed, k, sum(map(ord, shape))])
            rows.append((shape, *trial(graph, geometry, rng, every_start)))
    return rows


def summary(rows):
    moves = np.array([row[1] for row in rows])
    moved = moves > MOVED
    higher = sum(1 for row, m in zip(rows, moved) if m and row[3] > row[2])
    return (f"{len(rows)} trials: moved more than {MOVED:.1%} of the size in {moved.sum()} "
            f"({100 * moved.mean():.0f}%; to a higher-energy pose {higher}, to a lower-energy one "
            f"{moved.sum() - higher}); move median {np.median(moves):.1e}, worst {moves.max():.3f}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--trials", type=int, default=25, help="per shape")
    parser.add_argument("--shapes", default=f"{GRID},star,octopus,glyph A",
                        help=f"comma-separated: {GRID}, " + ", ".join(random_drags.SHAPES))
    parser.add_argument("--every-start", action="store_true")
    args = parser.parse_args(argv)
    shapes = args.shapes.split(",")
    rows = run(args.seed, args.trials, shapes, args.every_start)
    for shape in shapes:
        print(f"{shape}: " + summary([row for row in rows if row[0] == shape]))
    print("all: " + summary(rows))


if __name__ == "__main__":
    main()
