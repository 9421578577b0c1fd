"""Deform a graph so its handles reach their targets (paper sections 4 and 5).

:class:`Deformer` puts the pieces together: what is minimised (:mod:`solver.energy`, with
:mod:`solver.folds` and :mod:`solver.area`, on the free points of :mod:`solver.unknowns`), where
a solve starts (:mod:`solver.start`), the preconditioner (:mod:`solver.preconditioner`) and how
the minimum is found (:mod:`solver.optimizer`), each set by one :class:`~solver.options.Options`.

Handles are hard constraints in place of equation (6)'s soft term ``||C V - U||^2``: their
positions are set, not weighted, and their unknowns are eliminated, so moving handles only
changes right-hand sides.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np

from .area import AreaConstraint
from .energy import Energy, uncovered_points
from .folds import FoldPenalty
from .graph import default_spacing
from .hessian import NewtonMatrix
from .optimizer import minimise, newton
from .options import Options
from .preconditioner import choose
from .shapes import box_centre
from .start import CoarseCopies, CoarseStart, SimilarityStart
from .unknowns import Unknowns

__all__ = ["Deformer", "Solution"]


@dataclass
class Solution:
    """What :meth:`Deformer.solve` returns.

    Attributes
    ----------
    positions : (n, 2) float64 ndarray
        Deformed positions of all graph points; handles sit exactly on their targets.
    iterations : int
        Iterations run.
    energies : list of float
        Energy after each iteration (never increasing).
    converged : bool
        Whether the step fell below the tolerance before ``max_iterations``.
    factorizations : int
        Refreshes this solve made of the matrix that follows the pose: the whole Newton matrix
        (numeric refactorisations, one or two each) with Newton's method, the coarse Newton
        matrix with the two-grid; none with the paper's matrix alone.
    """

    positions: np.ndarray
    iterations: int = 0
    energies: list = field(default_factory=list)
    converged: bool = False
    factorizations: int = 0


def _area_set_by_handles(graph, unknowns):
    """Whether the handles alone set the shape's area: no boundary point is free, and some
    island is held by several points (islands at rest or carried by one point keep theirs)."""
    return not np.isin(graph.boundary, unknowns.free).any() and bool(np.any(unknowns.held_by > 1))


class Deformer:
    """The paper's deformer for one graph and one set of handles.

    Parameters
    ----------
    graph : solver.Graph
    handles : (h,) array_like of int
        Indices of graph points that are moved to targets. A connected part of the graph with
        no handle stays at rest; one with a single handle point moves with it, unturned.
    weights : dict, optional
        Weights of the energy terms ``"laplacian"``, ``"mvc"`` and ``"edge"``.
    preserve_area : bool
        Keep the total area (islands minus holes) equal to the rest area.
    newton : bool, optional
        ``None`` (default): up to ``options.newton_max_points`` points, Newton's method
        (:func:`solver.optimizer.newton`: the Newton matrix refactorised at every iterate, one
        symbolic analysis per handle set) from the lower-energy of the as-similar-as-possible
        pose and a solved coarse copy's pose. Above, from the coarse copy's pose, Newton's
        method with its system solved inexactly by conjugate gradients over the two-grid
        preconditioner of :mod:`solver.two_grid` (:mod:`solver.krylov`: the paper's factor,
        never refactorised, plus a Newton correction on a coarse copy); with ``preserve_area``,
        L-BFGS over that preconditioner. Above ``options.two_grid_max_points``, L-BFGS over
        ``A_f^T A_f`` alone.
        ``True``: Newton's method at any size, from the as-similar-as-possible pose.
        ``False``: the paper's way, L-BFGS on ``A_f^T A_f`` alone from the pose of a coarse
        copy of the shape; cheapest per iteration, slow to turn free limbs.
    prevent_flips : bool
        The paper's energy admits poses with folded (inverted) triangles in large bends (where a
        dragged region meets the rest, typically). With this on, triangles squeezed below
        ``options.fold_threshold`` (40%) of their rest area are pushed back open by a penalty
        (:mod:`solver.folds`); poses that squeeze none that far are the paper's minima unchanged.
    options : solver.Options, optional
        How the solver is built and run (iterations, tolerance, refresh schedule, coarse
        copies, fold penalty constants); the defaults when omitted.
    coarse_copies : solver.start.CoarseCopies, optional
        Where coarse copies of the shape are kept; pass the same one to the deformers of one
        graph (one per handle set or weights) to build its copy once. A new one by default.
    stiffness : (n,) array_like, optional
        A factor (> 0, default 1) on the energy terms of each point (:class:`solver.energy.Energy`):
        above 1 a region bends and stretches less. A coarse copy the solve may start from is
        solved without it (it only gives the start).
    normalise_density : bool
        On by default. Weight each kind of energy row by a power of ``default_spacing / graph.spacing``
        (:class:`solver.energy.Energy`'s ``reference_spacing``), so that a graph denser than
        :func:`~solver.graph.build_graph`'s default minimises the default graph's energy
        sampled more finely instead of one whose bending terms fade as ``h^2``. A graph at the
        default spacing gets exactly the paper's energy, and so do the coarse copies its solves
        start from; on other graphs the coarse copies are normalised too, so that they
        approximate the same functional as the graph.

    Raises
    ------
    ValueError
        Handles out of range or repeated, bad weights or stiffness, or ``preserve_area`` with no boundary point
        free to move (all are handles, or on islands without handles or with one handle point) and
        an island held by several points: the targets would set the area.
    """

    def __init__(self, graph, handles, weights=None, preserve_area=False, newton=None,
                 prevent_flips=False, options=None, coarse_copies=None, stiffness=None,
                 normalise_density=True):
        self.graph = graph
        self._lock = threading.Lock()
        self.options = Options() if options is None else options
        if not isinstance(self.options, Options):
            raise ValueError(f"options must be a solver.Options, got {type(self.options).__name__}")
        self.prevent_flips = bool(prevent_flips)
        self.preserve_area = bool(preserve_area)
        given = np.asarray(handles)
        if given.dtype == bool:
            raise ValueError("handles are point indices, got a boolean mask (np.flatnonzero(mask) gives them)")
        if given.size and not np.issubdtype(given.dtype, np.integer) and \
                not np.all(np.isfinite(given.astype(np.float64)) & (given == np.round(given))):
            raise ValueError(f"handles are point indices (whole numbers), got {given.ravel()[:5]}")
        handles = np.array(given, dtype=np.int64).ravel()  # a copy: the caller's may change
        if len(handles) and (handles.min() < 0 or handles.max() >= graph.n):
            raise ValueError(f"handle indices must be in [0, {graph.n}), got {handles.min()}..{handles.max()}")
        if len(np.unique(handles)) != len(handles):
            raise ValueError("a point is given as a handle twice")
        self.handles = handles
        self.normalise_density = bool(normalise_density)
        # The reference is the spacing build_graph picks for this outline by default, the
        # density the paper's weights were set at (its Table 1 graphs).
        reference = default_spacing(graph.geometry()) if self.normalise_density else None
        self.energy = Energy(graph, weights, stiffness, reference_spacing=reference)
        self._size = graph.size  # a bounding-box measure: once, not per solve
        self.unknowns = Unknowns(graph, handles)
        self.free = self.unknowns.free
        self._folds = self._area = None
        self._starts = []
        if self.preserve_area and _area_set_by_handles(graph, self.unknowns):
            raise ValueError("preserve_area needs a boundary point that can move: every boundary point is "
                             "a handle or lies on an island without handles, which stays at rest, or held by "
                             "one handle point, which it follows unturned")
        if len(self.free):
            self._build(weights, newton, CoarseCopies() if coarse_copies is None else coarse_copies, stiffness)

    def _build(self, weights, newton, copies, stiffness):
        graph, options, unknowns = self.graph, self.options, self.unknowns
        # A V = A_c c + [A_f 0; 0 A_f] v, kept coordinate-major (2, r) and flattened.
        self._free_block, self._free_block_transpose, self._fixed_columns = unknowns.split(self.energy.matrix)
        weight = np.asarray(abs(self._free_block_transpose).sum(axis=1)).ravel()
        if np.any(weight == 0.0):
            raise uncovered_points(self.energy, self.free[np.flatnonzero(weight[:len(self.free)] == 0.0)])
        if self.prevent_flips:
            # A fold is one triangle's event, whatever the density: each triangle is held open
            # as firmly as one at the reference spacing (the penalty scales with rest area, so
            # its weight goes up as the spacing's square goes down).
            fold_weight = options.fold_weight * self.energy.spacing_ratio ** 2
            # Beside a handle at least ``fold_weight_at_handles`` times the reference push: on a
            # dense graph the spacing's factor already holds every triangle more firmly than that.
            at_handles = max(1.0, options.fold_weight_at_handles * options.fold_weight / fold_weight) \
                if fold_weight > 0 else 1.0
            self._folds = FoldPenalty(graph, unknowns, options.fold_threshold, fold_weight, options.sliver_area,
                                      at_handles, stiffness)
        triangles = graph.triangles if self._folds is not None else None

        # A graph at the default spacing keeps the paper's energy and its solves their path bit
        # for bit, coarse start included (a coarse copy at 60 interior points would otherwise be
        # normalised; on the quick drags that was 85% / 97% within 1e-3 at 15 / 30 iterations
        # with the fold penalty instead of 82% / 94%, 73% / 88% without it instead of 76% / 91%).
        coarse_normalised = self.energy.density_normalised

        def make_deformer(coarse_graph, coarse_handles):
            # A coarse copy all of whose boundary points lie nearest handles cannot hold the area
            # (QA: such a handle set was refused): its pose is only a start, which the solve
            # projects onto the rest area.
            preserve_area = self.preserve_area and not _area_set_by_handles(
                coarse_graph, Unknowns(coarse_graph, coarse_handles))
            return Deformer(coarse_graph, coarse_handles, weights, preserve_area, newton=True,
                            prevent_flips=self.prevent_flips, options=options,
                            normalise_density=coarse_normalised)

        coarse = None if newton is True else self._coarse_copy(copies)
        self._preconditioner, self._newton = choose(self.energy, self.free, triangles, newton, options,
                                                    coarse, self.preserve_area)
        # Where a solve may start: the as-similar-as-possible pose (with a factorised Newton
        # matrix) and the pose of a solved coarse copy; with both, the one of lower energy.
        self._starts = []
        if isinstance(self._preconditioner, NewtonMatrix):
            self._starts.append(SimilarityStart(graph, unknowns))
        if coarse is not None:
            self._starts.append(CoarseStart(graph, self.handles, coarse, make_deformer))
        if self.preserve_area:
            self._area = AreaConstraint(graph, self.free, unknowns.fixed)

    def _coarse_copy(self, copies):
        """The coarse copy a solve starts from: above ``options.coarse_start_points`` points the
        default spacing (a few hundred points, whatever the fine graph's density); below, an
        outline of about ``options.coarse_interior`` interior points, or None when that is not
        ``options.coarse_ratio`` times smaller than the graph."""
        graph, options = self.graph, self.options
        if graph.n > options.coarse_start_points:
            return copies.get(graph)
        if graph.n < options.coarse_ratio * options.coarse_interior:
            return None
        copy = copies.get(graph, options.coarse_interior, options.coarse_detail)
        if copy is None or options.coarse_ratio * copy[0].n > graph.n:
            return None
        return copy

    def _start_candidates(self, targets, initial):
        """Poses (n, 2) a solve may start from, handles on their targets: ``initial``, or one
        per start strategy (the solve takes the one of lowest energy)."""
        rest = self.graph.points
        if initial is not None:
            positions = np.array(initial, dtype=np.float64)
            if positions.shape != rest.shape:
                raise ValueError(f"initial must have shape {rest.shape}, got {positions.shape}")
            if not np.all(np.isfinite(positions)):
                raise ValueError("initial has non-finite coordinates (NaN or inf)")
        else:  # every free point is set below; fixed ones are handles, resting or carried islands
            positions = rest.copy()
        positions[self.handles] = targets
        self.unknowns.place(positions, rest)
        if initial is not None or not self._starts:
            return [positions]
        candidates = []
        for start in self._starts:
            pose = start.pose(positions, targets)
            pose[self.unknowns.fixed] = positions[self.unknowns.fixed]
            candidates.append(pose)
        return candidates

    def solve(self, targets, max_iterations=None, tolerance=None, initial=None):
        """Deform so that ``handles[i]`` lands on ``targets[i]``.

        Parameters
        ----------
        targets : (h, 2) array_like
            Target of each handle, in the order given to the constructor.
        max_iterations : int, optional
            Default ``options.max_iterations``.
        tolerance : float, optional
            Stop once the next step would move no point more than ``tolerance * graph.size``.
            ``0.0`` runs exactly ``max_iterations``. Default ``options.tolerance``.
        initial : (n, 2) array_like, optional
            Warm start (its points on islands at rest or moved by one handle point are not
            read). By default the lower-energy of the as-similar-as-possible pose and a solved
            coarse copy's pose for the targets (see ``newton``), so the result depends on the
            targets alone.

        Returns
        -------
        Solution

        Raises
        ------
        ValueError
            Targets of the wrong shape or not finite; with ``preserve_area``, no pose with the rest
            area found near the start.
        FloatingPointError
            Targets so far from the shape (about 1e90 of its sizes) that the solve overflows.
        """
        # A solve keeps its working state on the deformer, and the factorisation releases the
        # interpreter's lock: two threads solving at once got each other's poses, then crashed
        # the process. Solves of one deformer take turns; separate deformers run in parallel.
        with self._lock:
            return self._solve(targets, max_iterations, tolerance, initial)

    def _solve(self, targets, max_iterations, tolerance, initial):
        targets = np.asarray(targets, dtype=np.float64)
        if targets.shape != (len(self.handles), 2):
            raise ValueError(f"targets must have shape ({len(self.handles)}, 2), got {targets.shape}")
        if not np.all(np.isfinite(targets)):
            raise ValueError("targets have non-finite coordinates (NaN or inf)")
        max_iterations = self.options.max_iterations if max_iterations is None else int(max_iterations)
        tolerance = self.options.tolerance if tolerance is None else float(tolerance)
        if max_iterations < 0 or tolerance < 0:
            raise ValueError("max_iterations and tolerance must be >= 0")

        candidates = self._start_candidates(targets, initial)
        positions = candidates[0]
        if len(self.free) == 0:
            return Solution(positions, 0, [], True)
        # The energy ignores translation, but rounding in the area (a sum of products of
        # coordinates) does not: a shape dragged 100 times its size away kept its area to only
        # 3e-6. So iterate on coordinates centred on the start pose.
        origin = box_centre(positions)
        fixed = positions[self.unknowns.fixed] - origin
        self._fixed_rows = (self._fixed_columns @ fixed).T.ravel()
        if self._area is not None:
            self._area.hold(fixed.T.ravel())
        if self._folds is not None:
            self._folds.hold(fixed)
        starts = [(candidate[self.free] - origin).T.ravel() for candidate in candidates]
        v = min(starts, key=lambda start: self.evaluate(start)[0]) if len(starts) > 1 else starts[0]
        try:
            optimiser = newton if self._newton else minimise
            result = optimiser(self, self._preconditioner, v, self.options, self._size,
                               max_iterations, tolerance, self._area)
        except RuntimeError as error:  # qdldl: a matrix that is not positive definite
            raise ValueError(f"the deformation system is singular ({error}): the weights or handles "
                             "leave part of the shape free to move without changing the energy") from None
        positions[self.free] = result.v.reshape(2, -1).T + origin
        if not np.all(np.isfinite(positions)):  # QA: targets 1e90 sizes away came back NaN, unsaid
            raise FloatingPointError("the solve gave non-finite positions")
        return Solution(positions, result.iterations, result.energies, result.converged, result.refreshes)

    # The objective the optimiser minimises (solver.optimizer.minimise), for the fixed points
    # that solve() holds.

    def evaluate(self, v):
        """Energy, half its gradient ``(2 f,)``, and the pose (rows ``A V`` ``(2, r)`` and the
        local fit) at free coordinates ``v`` (2 f,)."""
        rows = self._free_block @ v
        rows += self._fixed_rows
        rows = rows.reshape(2, -1)
        residual, fit = self.energy.local_step(rows)
        residual = residual.ravel()
        energy, gradient = float(residual @ residual), self._free_block_transpose @ residual
        if self._folds is not None:
            fold_energy, fold_gradient = self._folds.evaluate(v)
            if fold_gradient is not None:
                energy, gradient = energy + fold_energy, gradient + fold_gradient
        return energy, gradient, (rows, fit)

    def refresh(self, v, pose=None):
        """Refactor the preconditioner at ``v``, with the pose from :meth:`evaluate` if known."""
        rows, fit = pose if pose is not None else ((self._fixed_rows + self._free_block @ v).reshape(2, -1), None)
        self._preconditioner.factorize(rows, None if self._folds is None else self._folds.terms(v), fit)
