# SPDX-License-Identifier: GPL-3.0-or-later
"""The fold penalty's threshold: convergence against how far it moves the paper's own minima.

Run: .venv/bin/python benchmarks/fold_penalty.py [--seed N] [--thresholds 0.1,0.4,...]

For each threshold ``t`` (``Options.fold_threshold``; the push at zero area, ``fold_weight``,
kept at its default) it solves the random drags of ``benchmarks/random_drags.py`` at the
paper's size with the fold penalty and prints:

* within 1e-3 of the converged pose after 15 and 30 iterations (as ``random_drags.py`` counts);
* drags whose converged pose still has folded triangles;
* how far the converged pose lies from the paper's energy's own converged pose (no penalty,
  same start), over the drags where that one folds nothing: there the penalty is not needed,
  so any move is its price. Median, 90th percentile and worst, over the shape's size, and how
  many moved more than 1e-3;
* the median time of the 30-iteration solve.

A higher threshold starts the penalty's curvature earlier and more gently, which the optimiser
likes, and reaches into more poses that fold nothing.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import solver  # noqa: E402
from benchmarks import random_drags  # noqa: E402
from benchmarks.metrics import flipped  # noqa: E402


def sweep(seed, thresholds, drags=8):
    """Rows (one per threshold) of the measures above, as dicts."""
    cases = random_drags.cases(seed, "paper", drags=drags)
    plain = [random_drags.reference(solver.Deformer(case.graph, case.handles), case.targets) for case in cases]
    unfolded = [flipped(case.graph.points, pose.positions, case.graph.triangles) == 0
                for case, pose in zip(cases, plain)]
    rows = []
    for threshold in thresholds:
        options = solver.Options(fold_threshold=threshold)
        within, folded, moves, times = {15: 0, 30: 0}, 0, [], []
        for case, paper, keep in zip(cases, plain, unfolded):
            deformer = solver.Deformer(case.graph, case.handles, prevent_flips=True, options=options)
            converged = random_drags.reference(deformer, case.targets).positions
            for budget in within:
                start = time.perf_counter()
                pose = deformer.solve(case.targets, max_iterations=budget).positions
                if budget == 30:
                    times.append(time.perf_counter() - start)
                within[budget] += random_drags.pose_error(pose, converged, case.graph.size) <= random_drags.WITHIN
            folded += flipped(case.graph.points, converged, case.graph.triangles) > 0
            if keep:
                moves.append(random_drags.pose_error(converged, paper.positions, case.graph.size))
        rows.append({"threshold": threshold, "drags": len(cases), "within 15": within[15],
                     "within 30": within[30], "folded": folded, "moves": np.array(moves),
                     "ms": 1e3 * float(np.median(times))})
    return rows


def markdown(rows, seed):
    lines = [f"Seed {seed}, paper size, fold penalty (push at zero area {solver.Options().fold_weight:g}).", "",
             "| threshold | within 1e-3 after 15 / 30 | drags with folds at the minimum | "
             "move of the paper's unfolded minima: median / 90% / worst | moved > 1e-3 | ms median |",
             "|---|---|---|---|---|---|"]
    for row in rows:
        moves, n = row["moves"], row["drags"]
        lines.append(f"| {row['threshold']:g} | {row['within 15']}/{n} / {row['within 30']}/{n} | {row['folded']} | "
                     f"{np.median(moves):.1e} / {np.quantile(moves, 0.9):.1e} / {moves.max():.1e} | "
                     f"{int((moves > 1e-3).sum())} of {len(moves)} | {row['ms']:.1f} |")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=2006)
    parser.add_argument("--thresholds", default="0.1,0.2,0.3,0.4,0.5,0.7")
    parser.add_argument("--drags", type=int, default=8, help="drags per shape (default 8)")
    args = parser.parse_args(argv)
    thresholds = [float(value) for value in args.thresholds.split(",")]
    print(markdown(sweep(args.seed, thresholds, args.drags), args.seed))


if __name__ == "__main__":
    main()
