# SPDX-License-Identifier: GPL-3.0-or-later
"""Two sets of solver options on the same random drags, solved in turns.

Run: .venv/bin/python benchmarks/options_ab.py --b KEY=VALUE[,KEY=VALUE...] [--a ...] [--seed N]
[--size paper|5k] [--drags 3] [--plain] [--repeats 3]

Each drag of :mod:`benchmarks.random_drags` is solved by two deformers that differ only in their
:class:`solver.Options` (``--a``, default the defaults, and ``--b``), each measured against its
own converged pose (:func:`benchmarks.random_drags.reference`). Their 30-iteration solves are
timed in turns, A B B A ..., so that a busy spell on a shared machine slows both alike; only this
interleaved ratio says anything about seconds (the record's own time columns move by a fifth
between runs of the same code). Prints, per side, how many solves are within 1e-3 of the size
of the converged pose after 15 and 30 iterations, iterations, milliseconds, and how many drags
converge to a minimum of higher energy than the other side's; then the time ratio B / A per drag
(median) and in total.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import fields

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import solver  # noqa: E402
from benchmarks import random_drags  # noqa: E402

__all__ = ["parse_options", "compare", "report"]


def parse_options(text):
    """``"key=value,key=value"`` -> :class:`solver.Options` (empty text: the defaults)."""
    kinds = {item.name: item.type for item in fields(solver.Options)}
    values = {}
    for pair in filter(None, (text or "").split(",")):
        key, _, value = pair.partition("=")
        if key not in kinds:
            raise ValueError(f"unknown option {key!r}; known: {', '.join(kinds)}")
        values[key] = int(value) if kinds[key] == "int" else float(value)
    return solver.Options(**values)


def _solve_both(deformers, targets, repeats):
    """Time both deformers' 30-iteration solves in turns; their first solutions and median
    seconds."""
    times, first = ([], []), [None, None]
    for round_ in range(repeats):
        for side in ((0, 1) if round_ % 2 == 0 else (1, 0)):
            start = time.perf_counter()
            solution = deformers[side].solve(targets, max_iterations=30)
            times[side].append(time.perf_counter() - start)
            first[side] = first[side] or solution
    return first, [float(np.median(t)) for t in times]


def compare(options, seed, size="paper", drags=3, prevent_flips=True, repeats=3):
    """One row per drag: for each side, errors after 15 and 30 iterations, iterations, the
    converged pose's energy and the median time.

    Parameters
    ----------
    options : (solver.Options, solver.Options)
    seed : int
    size : {"paper", "5k"}
    drags : int
        Drags per shape.
    prevent_flips : bool
    repeats : int

    Returns
    -------
    list of dict
        ``case`` and, per side ``s`` in ``(0, 1)``: ``(s, "error 15")``, ``(s, "error 30")``,
        ``(s, "iterations")``, ``(s, "ref energy")``, ``(s, "seconds")``.
    """
    rows = []
    for case in random_drags.cases(seed, size, None, drags):
        deformers = [solver.Deformer(case.graph, case.handles, prevent_flips=prevent_flips, options=o)
                     for o in options]
        references = [random_drags.reference(d, case.targets, random_drags.REFERENCE_ITERATIONS[size])
                      for d in deformers]  # also the warm-up
        full, seconds = _solve_both(deformers, case.targets, repeats)
        row = {"case": case.name}
        for side, (deformer, ref, solution) in enumerate(zip(deformers, references, full)):
            short = solution if solution.converged and solution.iterations <= 15 else \
                deformer.solve(case.targets, max_iterations=15)
            for label, pose in (("error 15", short), ("error 30", solution)):
                row[side, label] = random_drags.pose_error(pose.positions, ref.positions, case.graph.size)
            row[side, "iterations"] = solution.iterations
            row[side, "ref energy"] = float(ref.energies[-1]) if len(ref.energies) else 0.0
            row[side, "seconds"] = seconds[side]
        rows.append(row)
    return rows


def report(rows, labels=("A", "B")):
    """Text lines summarising :func:`compare`'s rows."""
    lines = []
    for side, label in enumerate(labels):
        def column(key):
            return np.array([row[side, key] for row in rows])
        other = 1 - side
        higher = sum(row[side, "ref energy"] > row[other, "ref energy"] * (1 + 1e-6) for row in rows)
        ms = column("seconds") * 1e3
        lines.append(f"{label}: within 1e-3 after 15 {np.sum(column('error 15') <= random_drags.WITHIN)}/{len(rows)}, "
                     f"after 30 {np.sum(column('error 30') <= random_drags.WITHIN)}/{len(rows)}; iterations "
                     f"median {np.median(column('iterations')):.0f}, worst {column('iterations').max()}; ms "
                     f"median {np.median(ms):.1f}, worst {ms.max():.1f}; converged to a higher minimum "
                     f"than the other: {higher}")
    ratios = [row[1, "seconds"] / row[0, "seconds"] for row in rows]
    total = sum(row[1, "seconds"] for row in rows) / sum(row[0, "seconds"] for row in rows)
    lines.append(f"time {labels[1]} / {labels[0]}: median per drag {np.median(ratios):.3f}, in total {total:.3f}")
    return lines


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--a", default="", help="options of side A as key=value,... (default: the defaults)")
    parser.add_argument("--b", required=True, help="options of side B as key=value,...")
    parser.add_argument("--seed", type=int, default=2006)
    parser.add_argument("--size", default="paper", choices=list(random_drags.SIZES))
    parser.add_argument("--drags", type=int, default=3, help="drags per shape (default 3)")
    parser.add_argument("--plain", action="store_true", help="without the fold penalty")
    parser.add_argument("--repeats", type=int, default=3, help="timed solves per side and drag")
    args = parser.parse_args(argv)
    try:
        options = (parse_options(args.a), parse_options(args.b))
    except ValueError as error:
        parser.error(str(error))
    rows = compare(options, args.seed, args.size, args.drags, not args.plain, args.repeats)
    print("\n".join(report(rows, (f"A ({args.a or 'defaults'})", f"B ({args.b})"))))


if __name__ == "__main__":
    main()
