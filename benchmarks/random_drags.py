# SPDX-License-Identifier: GPL-3.0-or-later
"""Convergence and speed on seeded random drags: the benchmark of record for the optimiser.

Run: .venv/bin/python benchmarks/random_drags.py [--quick] [--seed N] [--doc PATH] [--verbose]
(``--sizes paper,5k``, ``--configs default,plain``, ``--shapes NAME,...``, ``--drags N``;
``--profile`` prints where the solves' time goes instead).

Eleven shapes (glyphs with holes, traced bitmaps, thin limbs, three islands, a star), each at
the paper's size (400-900 graph points) and at about 5,000 points, get ``--drags`` random drags
each (default 8). A drag has two or three handle regions: small disks of graph points (radius
4-6% of the shape's size) at random boundary or interior places, far apart, the first two on
the same island. One of those two is moved 15-45% of the size in a random direction and turned
up to 60 degrees either way about its centre; the others stay pinned, except that with three
regions one of them may move a little (up to 5% of the size). Drags are drawn from the shape's
outline, not its graph, so both sizes get the same drags; drag k of a shape is the same
whatever ``--drags`` and ``--shapes`` are.

Each drag is solved as the add-on solves (default tolerance, at most 15 and at most 30
iterations), with the fold penalty (``prevent_flips=True``, the add-on's default: "default")
and without ("plain"). Measures:

* error: the largest distance of a point from the *converged pose*, over the shape's size
  (``graph.size``, its bounding-box diagonal); a drag counts as converged at 15 or 30 iterations
  when the error is at most 1e-3;
* the converged pose is what the same deformer reaches from the same default start given many
  more iterations and a far tighter tolerance (:func:`reference`); those that stop at their
  iteration cap are listed;
* folds: triangles whose signed area changed sign (``benchmarks.metrics.flipped``) in the
  30-iteration pose, and in the converged pose (folds there belong to the energy, not to the
  optimiser);
* time: the 30-iteration solve (what the add-on runs), median of ``--repeats`` solves after a
  warm-up (the reference solve), in turns with libigl's 10 ARAP iterations on the same
  triangles, handles and targets, and their ratio (ours / libigl; below 1 means ours is
  faster). Building either is not timed. libigl gets one extra pinned point on each island
  without a handle, which it cannot leave free and ours leaves at rest.

To try another optimiser, pass ``make_deformer(graph, handles, prevent_flips)`` to
:func:`measure` or :func:`run`: it must return an object whose ``solve(targets,
max_iterations=None, tolerance=None)`` returns something with ``positions``, ``iterations``,
``converged`` and ``energies`` as :class:`solver.Solution` has, and whose path does not depend
on ``max_iterations`` (a solve that stops by tolerance within 15 iterations is taken as the
15-iteration solve too).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import zlib
from dataclasses import dataclass

import numpy as np
import shapely

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import solver  # noqa: E402
from benchmarks.metrics import flipped  # noqa: E402
from benchmarks.shapes import (drawn_cat, glyph, horse, islands, octopus, star, stick_figure,  # noqa: E402
                               traced_blob)
from benchmarks.solver_speed import libigl_arap  # noqa: E402
from solver.rigging.handles import select_region  # noqa: E402

__all__ = ["SHAPES", "SIZES", "CONFIGS", "Case", "cases", "sized_graph", "random_drag", "place_drag",
           "default_deformer", "reference", "pose_error", "measure", "run", "summary", "by_shape", "oddities",
           "markdown"]

SHAPES = {
    "glyph g": lambda: glyph("g"),
    "glyph &": lambda: glyph("&"),
    "glyph A": lambda: glyph("A"),
    "glyph 8": lambda: glyph("8"),
    "star": star,
    "stick figure": stick_figure,
    "octopus": octopus,
    "islands": islands,
    "cat (traced)": drawn_cat,
    "blob (traced)": traced_blob,
    "horse (traced)": horse,
}
"""Shape name -> function returning its rings."""

# Graph sizes: the range of points a graph must fall in, and the count aimed at when the first
# spacing misses it. "paper" starts from build_graph's default spacing (the paper's Table 1
# shapes have 480-830 points); "5k" from a lattice of 4,300 points, as solver_speed.py does.
SIZES = {"paper": ((400, 900), 650, None), "5k": ((4000, 6000), 5000, 4300)}
CONFIGS = {"default": True, "plain": False}
"""Configuration name -> ``prevent_flips``: the add-on's default, and without the fold penalty."""

# Drag parameters, as fractions of the shape's size (its bounding-box diagonal).
RADIUS = (0.04, 0.06)
MOVE = (0.15, 0.45)
TURN_DEGREES = 60.0
NUDGE = 0.05
# Handle region centres at least this far apart: nearer, the drag only squeezes what lies
# between them, which tells little about convergence.
APART = 0.25
# The bar for "converged": the 1e-3 of the size.
WITHIN = 1e-3
# The converged pose: same deformer, same start, this many iterations at most and a tolerance
# far below the default 1e-4. At 5,000 points an iteration costs ~10x more, and with the fold
# penalty some drags crawl on for well over 1,500 iterations (a 5k star: still 1.8e-2 of the
# size from its 1,500-iteration pose after 600), so the cap there is what keeps a full run near
# ten minutes. References that stop at their cap are reported, and their errors are only the
# distance to a pose further down the same path.
REFERENCE_ITERATIONS = {"paper": 2000, "5k": 300}
REFERENCE_TOLERANCE = 1e-9


@dataclass
class Case:
    """One random drag on one graph.

    Attributes
    ----------
    name : str
        ``"<shape> #<k>"``.
    shape, size : str
        Keys of ``SHAPES`` and ``SIZES``.
    graph : solver.Graph
        Shared by every drag of the shape at that size.
    handles : (h,) int ndarray
        All regions' points, region after region.
    targets : (h, 2) float ndarray
    regions : list of int ndarray
        Each region's points (disjoint).
    moved : int
        Index of the dragged region.
    """

    name: str
    shape: str
    size: str
    graph: solver.Graph
    handles: np.ndarray
    targets: np.ndarray
    regions: list
    moved: int


# --------------------------------------------------------------------------------------------
# Graphs and drags

def sized_graph(rings, size):
    """A graph of ``rings`` whose point count falls in the range of ``SIZES[size]``.

    Boundary points grow as 1/spacing and interior points as 1/spacing^2, so a shape with long
    thin limbs overshoots a lattice-based spacing; a few rescaled tries bring it into range.
    """
    (low, high), aim, lattice = SIZES[size]
    area = solver.shapes.shape_geometry(rings).area
    spacing = None if lattice is None else np.sqrt(area / lattice)
    for _ in range(6):
        graph = solver.build_graph(rings, spacing=spacing)
        if low <= graph.n <= high:
            return graph
        current = solver.graph.default_spacing(solver.shapes.shape_geometry(rings)) if spacing is None else spacing
        spacing = current * np.sqrt(graph.n / aim)
    raise RuntimeError(f"no spacing gives {low}-{high} points (last: {graph.n})")


def _drag_rng(seed, shape, index):
    """Generator of drag ``index`` of ``shape``: independent of which shapes and how many drags
    are asked for, so ``--shapes`` and ``--drags`` pick subsets of the same drags."""
    return np.random.default_rng([seed, zlib.crc32(shape.encode()), index])


def _random_place(rng, piece):
    """A point on the outline or inside ``piece`` (a shapely geometry), either with even odds."""
    if rng.random() < 0.5:
        outline = piece.boundary
        return np.asarray(shapely.line_interpolate_point(outline, rng.random() * outline.length).coords[0])
    low, high = np.asarray(piece.bounds[:2]), np.asarray(piece.bounds[2:])
    while True:  # rejection sampling; every shape here fills a good part of its box
        candidates = low + rng.random((32, 2)) * (high - low)
        inside = shapely.contains_xy(piece, candidates[:, 0], candidates[:, 1])
        if inside.any():
            return candidates[np.argmax(inside)]


def _centres(rng, geometry, count, size):
    """``count`` region centres at least ``APART * size`` apart (relaxed if a shape is too small
    for it). The first two lie on the same island, picked with odds by area: islands share no
    edges, so a region alone on its island only carries that island along rigidly, and a drag
    whose dragged region had no partner would deform nothing."""
    pieces = list(getattr(geometry, "geoms", [geometry]))
    areas = np.array([piece.area for piece in pieces])
    island = pieces[rng.choice(len(pieces), p=areas / areas.sum())]
    apart = APART * size
    centres = []
    for k in range(count):
        piece = island if k < 2 else geometry
        for attempt in range(200):
            place = _random_place(rng, piece)
            if all(np.linalg.norm(place - c) >= apart for c in centres):
                break
            if attempt % 50 == 49:
                apart *= 0.8
        centres.append(place)
    return np.array(centres)


def _turn_about(centre, degrees, shift):
    """Affine map (M, t) turning by ``degrees`` about ``centre`` then shifting by ``shift``."""
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    m = np.array([[c, -s], [s, c]])
    return m, centre - m @ centre + shift


def random_drag(rng, geometry):
    """Region centres, radii and motions of one drag on ``geometry`` (shapely).

    Returns
    -------
    centres : (k, 2) ndarray
    radii : (k,) ndarray
    motions : list of (M (2, 2), t (2,))
        ``target = rest @ M.T + t`` for each region's points.
    moved : int
        The dragged region.
    """
    x0, y0, x1, y1 = geometry.bounds
    size = float(np.hypot(x1 - x0, y1 - y0))
    count = int(rng.integers(2, 4))
    centres = _centres(rng, geometry, count, size)
    radii = rng.uniform(*RADIUS, count) * size
    moved = int(rng.integers(2))  # one of the two regions that share an island
    direction = rng.uniform(0, 2 * np.pi)
    shift = rng.uniform(*MOVE) * size * np.array([np.cos(direction), np.sin(direction)])
    turn = rng.uniform(0, TURN_DEGREES) * rng.choice([-1.0, 1.0])
    motions = [(np.eye(2), np.zeros(2))] * count
    motions[moved] = _turn_about(centres[moved], turn, shift)
    if count == 3 and rng.random() < 0.5:
        other = (moved + 1 + int(rng.integers(2))) % 3  # either of the other two
        angle = rng.uniform(0, 2 * np.pi)
        motions[other] = (np.eye(2), rng.uniform(0, NUDGE) * size * np.array([np.cos(angle), np.sin(angle)]))
    return centres, radii, motions, moved


def place_drag(graph, centres, radii, motions):
    """Graph points of each region (disjoint, at least 3 each) and the handles' targets."""
    taken = np.zeros(graph.n, dtype=bool)
    regions = []
    for centre, radius in zip(centres, radii):
        region = np.sort(select_region(graph.points, centre, radius, taken=taken))
        taken[region] = True
        regions.append(region)
    targets = [graph.points[r] @ m.T + t for r, (m, t) in zip(regions, motions)]
    return np.concatenate(regions), np.concatenate(targets), regions


def cases(seed, size="paper", shapes=None, drags=8):
    """The random drags of ``shapes`` (default all of ``SHAPES``) at one size.

    Parameters
    ----------
    seed : int
    size : {"paper", "5k"}
    shapes : sequence of str, optional
    drags : int
        Drags per shape; drag k is the same whatever ``drags`` and ``shapes`` are.

    Returns
    -------
    list of Case
    """
    out = []
    for shape in shapes or list(SHAPES):
        rings = SHAPES[shape]()
        geometry = solver.shapes.shape_geometry(rings)
        graph = sized_graph(rings, size)
        for k in range(drags):
            centres, radii, motions, moved = random_drag(_drag_rng(seed, shape, k), geometry)
            handles, targets, regions = place_drag(graph, centres, radii, motions)
            out.append(Case(f"{shape} #{k}", shape, size, graph, handles, targets, regions, moved))
    return out


# --------------------------------------------------------------------------------------------
# Measuring

def default_deformer(graph, handles, prevent_flips):
    """The solver as the add-on builds it, except for ``prevent_flips``."""
    return solver.Deformer(graph, handles, prevent_flips=prevent_flips)


def reference(deformer, targets, max_iterations=2000, tolerance=REFERENCE_TOLERANCE):
    """The converged pose: ``deformer`` solved from its default start until no point would move
    more than ``tolerance`` of the size, or ``max_iterations``. Check ``.converged``."""
    return deformer.solve(targets, max_iterations=max_iterations, tolerance=tolerance)


def pose_error(positions, converged, size):
    """The largest distance of a point of ``positions`` from ``converged`` (both (n, 2)), over
    ``size``."""
    return float(np.linalg.norm(positions - converged, axis=1).max() / size)


def _energy(solution):
    return float(solution.energies[-1]) if len(solution.energies) else float("nan")


def _timed_rounds(ours, theirs, repeats):
    """Call ``ours`` and ``theirs`` in turns ``repeats`` times, so a busy spell on a shared
    machine slows both alike. Returns ours' first result and both median times in seconds."""
    times = [[], []]
    first = None
    for _ in range(repeats):
        start = time.perf_counter()
        result = ours()
        times[0].append(time.perf_counter() - start)
        first = result if first is None else first
        start = time.perf_counter()
        theirs()
        times[1].append(time.perf_counter() - start)
    return first, float(np.median(times[0])), float(np.median(times[1]))


def _libigl_handles(case):
    """The case's handles and targets, plus one point pinned at rest on each island without a
    handle: ours leaves such islands at rest, libigl's precomputation refuses a part that
    nothing holds (its system is singular)."""
    labels = case.graph.components()
    loose = np.setdiff1d(np.unique(labels), labels[case.handles])
    if len(loose) == 0:
        return case.handles, case.targets
    anchors = np.array([np.flatnonzero(labels == label)[0] for label in loose])
    return (np.concatenate([case.handles, anchors]),
            np.concatenate([case.targets, case.graph.points[anchors]]))


def measure(case, make_deformer=default_deformer, prevent_flips=True, repeats=5,
            reference_iterations=None):
    """Solve one case as the add-on does and time it beside libigl.

    The reference solve comes first and doubles as the warm-up; the first timed 30-iteration
    solve is the pose measured. A 30-iteration solve that met the tolerance within 15
    iterations is also the 15-iteration one (the path of a solve does not depend on its cap), so
    only the others solve again with a cap of 15.

    Returns
    -------
    dict
        ``error 15``/``error 30`` (to the reference, in sizes), ``within 15``/``within 30``
        (error <= ``WITHIN``), ``iterations 15/30``, ``converged 15/30`` (the solver's own stop),
        ``flips`` (30-iteration pose), reference ``ref iterations``, ``ref converged``,
        ``ref flips``, ``ref energy`` and ``energy 30``, ``ms`` (ours), ``libigl ms``, ``ratio``.
    """
    graph, targets = case.graph, case.targets
    deformer = make_deformer(graph, case.handles, prevent_flips)
    ref = reference(deformer, targets, reference_iterations or REFERENCE_ITERATIONS[case.size])
    _, igl_solve = libigl_arap(graph, *_libigl_handles(case), 10)
    igl_solve()
    full, ours, theirs = _timed_rounds(lambda: deformer.solve(targets, max_iterations=30), igl_solve,
                                       repeats)
    short = full
    if not (full.converged and full.iterations <= 15):
        short = deformer.solve(targets, max_iterations=15)
    errors = [pose_error(s.positions, ref.positions, graph.size) for s in (short, full)]
    return {
        "case": case.name, "shape": case.shape, "size": case.size, "points": graph.n,
        "error 15": errors[0], "error 30": errors[1],
        "within 15": errors[0] <= WITHIN, "within 30": errors[1] <= WITHIN,
        "iterations 15": short.iterations, "iterations 30": full.iterations,
        "converged 15": bool(short.converged), "converged 30": bool(full.converged),
        "flips": flipped(graph.points, full.positions, graph.triangles),
        "ref iterations": ref.iterations, "ref converged": bool(ref.converged),
        "ref flips": flipped(graph.points, ref.positions, graph.triangles),
        "ref energy": _energy(ref), "energy 30": _energy(full),
        "ms": ours * 1e3, "libigl ms": theirs * 1e3, "ratio": ours / theirs,
    }


def run(seed, sizes=("paper", "5k"), configs=("default", "plain"), shapes=None, drags=8,
        make_deformer=default_deformer, repeats=None, log=None):
    """Measure every case at every size in every configuration.

    Returns
    -------
    list of dict
        :func:`measure`'s rows with ``config`` added.
    """
    rows = []
    for size in sizes:
        for case in cases(seed, size, shapes, drags):
            for config in configs:
                row = measure(case, make_deformer, CONFIGS[config],
                              repeats or (5 if size == "paper" else 3))
                rows.append({"config": config, **row})
            if log and case.name.endswith(f"#{drags - 1}"):
                log(f"measured {case.shape} at {size} ({case.graph.n} points)")
    return rows


def profile(seed, size="paper", prevent_flips=True, shapes=None, drags=8, top=20):
    """Where the time of the add-on's solves goes: cProfile over one 30-iteration solve of every
    case (after a warm-up solve each, as :func:`measure` times them), the ``top`` functions by
    their own time. Returns the report as text."""
    import cProfile
    import io
    import pstats
    solves = []
    for case in cases(seed, size, shapes, drags):
        deformer = default_deformer(case.graph, case.handles, prevent_flips)
        deformer.solve(case.targets, max_iterations=30)
        solves.append((deformer, case.targets))
    profiler = cProfile.Profile()
    profiler.enable()
    for deformer, targets in solves:
        deformer.solve(targets, max_iterations=30)
    profiler.disable()
    report = io.StringIO()
    pstats.Stats(profiler, stream=report).sort_stats("tottime").print_stats(top)
    return report.getvalue()


# --------------------------------------------------------------------------------------------
# Tables

def _share(rows, key):
    hits = sum(row[key] for row in rows)
    return f"{hits}/{len(rows)} ({100 * hits / len(rows):.0f}%)"


def _spread(values, digits="{:.3g}"):
    return f"{digits.format(np.median(values))} / {digits.format(np.max(values))}"


def _folds(rows, key):
    folded = [row[key] for row in rows if row[key]]
    return f"{len(folded)} ({sum(folded)})"


def _cells(rows):
    """Summary cells of a group of rows (one per drag)."""
    errors = [row["error 30"] for row in rows]
    return [
        _share(rows, "within 15"), _share(rows, "within 30"),
        f"{np.median(errors):.1e} / {max(errors):.1e}",
        _spread([row["iterations 30"] for row in rows], "{:.0f}"),
        str(sum(not row["converged 30"] for row in rows)),
        _folds(rows, "flips"), _folds(rows, "ref flips"),
        _spread([row["ratio"] for row in rows], "{:.2f}"),
        _spread([row["ms"] for row in rows], "{:.1f}"),
        f"{np.median([row['libigl ms'] for row in rows]):.1f}",
        str(sum(not row["ref converged"] for row in rows)),
    ]


_HEADER = ["within 1e-3 at 15 it.", "within 1e-3 at 30 it.", "error at 30 it. median / worst",
           "iterations median / worst", "at the 30 cap", "drags with folds (triangles)",
           "folds in the converged pose", "ours / libigl median / worst", "ours ms median / worst",
           "libigl ms median", "references at their cap"]


def _table(first, groups):
    lines = ["| " + " | ".join(first + _HEADER) + " |", "|" + "---|" * (len(first) + len(_HEADER))]
    for keys, rows in groups:
        lines.append("| " + " | ".join(list(keys) + _cells(rows)) + " |")
    return lines


def _group(rows, *keys):
    groups = {}
    for row in rows:
        groups.setdefault(tuple(row[k] for k in keys), []).append(row)
    return list(groups.items())


def summary(rows):
    """Markdown lines: one row per (size, configuration)."""
    groups = [((size, config, f"{len(g)}", f"{min(r['points'] for r in g)}-{max(r['points'] for r in g)}"), g)
              for (size, config), g in _group(rows, "size", "config")]
    return _table(["size", "configuration", "drags", "graph points"], groups)


def by_shape(rows):
    """Markdown lines: one row per (size, configuration, shape)."""
    return _table(["size", "configuration", "shape"], _group(rows, "size", "config", "shape"))


def oddities(rows):
    """Lines on references that stopped at their cap, per size and configuration, and on any
    that ended above the 30-iteration pose's energy (a plugged-in optimiser whose long run
    found another minimum; ours cannot, as its long run continues the same path)."""
    lines = []
    for (size, config), group in _group(rows, "size", "config"):
        capped = [row for row in group if not row["ref converged"]]
        if capped:
            names = ", ".join(row["case"] for row in capped)
            lines.append(f"* {size}, {config}: {len(capped)} of {len(group)} references stopped at their "
                         f"cap of {capped[0]['ref iterations']} iterations: {names}")
    for row in rows:
        if row["energy 30"] < row["ref energy"] * (1 - 1e-9):
            lines.append(f"* reference of {row['case']} at {row['size']} ({row['config']}) ended at a "
                         f"higher energy ({row['ref energy']:.6g}) than the 30-iteration pose "
                         f"({row['energy 30']:.6g}): another minimum")
    return lines


def machine():
    """CPU model, cores and versions, for the record."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as handle:
            model = next(line.split(":", 1)[1].strip() for line in handle if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    import scipy

    try:
        from importlib.metadata import version
        igl = version("libigl")
    except Exception:  # noqa: BLE001 - only for the record
        igl = "?"
    return (f"{model}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, Python "
            f"{platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, libigl {igl}")


def markdown(rows, seed, command, seconds, verbose=False):
    """The report: what was run and where, the summary table, oddities, and per shape."""
    lines = [f"Seed {seed}. Command: `{command}` ({seconds:.0f} s).", "",
             f"Machine: {machine()}.", "",
             f"Converged pose: the same deformer from the same start with tolerance "
             f"{REFERENCE_TOLERANCE:g} and at most {REFERENCE_ITERATIONS['paper']} iterations at paper size, "
             f"{REFERENCE_ITERATIONS['5k']} at 5k. Error: the largest point distance to it over the shape's "
             "size; \"within 1e-3\" counts solves with the default tolerance (1e-4) capped at 15 or 30 "
             "iterations whose error is at most 1e-3. \"default\" is the add-on's configuration "
             "(`prevent_flips=True`), \"plain\" is without the fold penalty. At the 30 cap: solves that "
             "stopped by the cap, not the tolerance. Folds: triangles flipped against rest in the "
             "30-iteration pose and in the converged pose (drags with any, and in brackets the "
             "triangles). Time: the 30-iteration solve, median of several after a warm-up, in turns "
             "with libigl's 10 ARAP iterations on the same triangles, handles and targets.", ""]
    lines += summary(rows)
    odd = oddities(rows)
    lines += ["", "References: all converged." if not odd else
              "References (the errors of these drags are distances to a pose further down the "
              "solve's own path, not to its minimum):", ""] + odd
    if verbose:
        lines += ["", "Per shape:", ""] + by_shape(rows)
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=2006, help="drag seed (default 2006)")
    parser.add_argument("--sizes", help="comma-separated: paper, 5k (default both)")
    parser.add_argument("--configs", default="default,plain", help="comma-separated: default, plain")
    parser.add_argument("--shapes", help="comma-separated names from SHAPES (default all)")
    parser.add_argument("--drags", type=int, help="drags per shape (default 8)")
    parser.add_argument("--repeats", type=int, help="timed solves per case (default 5, 3 at 5k)")
    parser.add_argument("--quick", action="store_true",
                        help="defaults of 3 drags per shape and the paper size only")
    parser.add_argument("--verbose", action="store_true", help="also print a per-shape table")
    parser.add_argument("--doc", help="also write the markdown report to this file")
    parser.add_argument("--profile", action="store_true",
                        help="instead, profile the 30-iteration solves of the first size and configuration")
    args = parser.parse_args(argv)
    sizes = (args.sizes or ("paper" if args.quick else "paper,5k")).split(",")
    drags = args.drags or (3 if args.quick else 8)
    shapes = args.shapes.split(",") if args.shapes else None
    configs = args.configs.split(",")
    for names, known in ((shapes or [], SHAPES), (sizes, SIZES), (configs, CONFIGS)):
        for name in names:
            if name not in known:
                parser.error(f"unknown name {name!r}; known: {', '.join(known)}")

    if args.profile:
        print(profile(args.seed, sizes[0], CONFIGS[configs[0]], shapes, drags))
        return
    start = time.perf_counter()
    rows = run(args.seed, sizes, configs, shapes, drags, repeats=args.repeats,
               log=lambda message: print(message, file=sys.stderr, flush=True))
    seconds = time.perf_counter() - start
    command = "python benchmarks/random_drags.py " + " ".join(sys.argv[1:] if argv is None else argv)
    text = markdown(rows, args.seed, command.strip(), seconds, verbose=args.verbose)
    print(text)
    if args.doc:
        with open(args.doc, "w") as handle:
            handle.write(text)


if __name__ == "__main__":
    main()
