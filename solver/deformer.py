"""Deform a graph so its handles reach their targets (paper sections 4 and 5).

Handles are hard constraints: their positions are set, not weighted, and their unknowns are
eliminated. Moving handles only changes right-hand sides.

The paper iterates ``V <- (A^T A)^-1 A^T b(V)`` (equation 9): a preconditioned gradient step on
``E(V) = ||A V - b(V)||^2`` with a matrix that treats turning an edge as stiff, so free limbs
creep toward their pose over hundreds of iterations. We keep that matrix, factorised once per
handle set, and add what it misses: a Newton correction on a coarse copy of the shape
(:mod:`solver.two_grid`), whose small matrix follows the pose. L-BFGS uses the two as its
initial inverse Hessian, so an iteration costs one back-substitution with the paper's factor
plus one with the coarse one, and a backtracking line search makes every iteration lower the
energy. Solves start from the as-similar-as-possible pose (one linear solve that turns free
limbs with what they hang from), or on large graphs from the pose of the coarse copy.
``newton=True`` takes projected Newton steps on the whole graph instead (:mod:`solver.hessian`:
one numeric refactorisation each, the symbolic analysis shared).

With ``preserve_area`` the total area is a hard constraint (section 5). Each iteration makes one
extra solve ``d = H^-1 J^T`` as the paper does with ``(A^T A)^-1 J^T``; the step is projected onto
the constraint's tangent in that metric and, since area is quadratic in the positions, the exact
correction along ``d`` is a root of a quadratic: the area is met to rounding at every iterate.

With ``prevent_flips`` the energy gains the fold penalty of :mod:`solver.folds`, with its
Gauss-Newton terms in the Newton matrices and, through a low-rank update, in the two-grid's
smoother.
"""

from __future__ import annotations

import hashlib
from collections import deque
from dataclasses import dataclass, field

import numpy as np
import qdldl
from scipy.sparse import block_diag, coo_matrix, identity, triu
from scipy.spatial import cKDTree

from .binding import bind
from .energy import Energy, similarity_rows
from .folds import FoldPenalty
from .graph import build_graph
from .hessian import Hessian, PaperMatrix
from .outline import outline_graph
from .shapes import box_centre
from .two_grid import TwoGrid

__all__ = ["Deformer", "Solution", "DEFAULT_MAX_ITERATIONS", "DEFAULT_TOLERANCE"]

DEFAULT_MAX_ITERATIONS = 30
# Stop when the next step would move no point more than this fraction of the shape's size.
DEFAULT_TOLERANCE = 1e-4
# Refreshes of the pose-dependent matrix at most per solve (the two-grid's coarse Newton matrix
# or, with newton=True, the whole Newton matrix), made while steps are larger than NEWTON_UNTIL
# times the shape's size; then L-BFGS reuses the last one.
NEWTON_STEPS = 4
NEWTON_UNTIL = 1e-2
# A solve still running at LATE_REFRESH_FROM iterations with steps above LATE_UNTIL times the
# size is crawling along a flat valley (a free limb swinging about a handle, two handles pulling
# against each other) where the last refresh no longer describes the pose: it refreshes every
# LATE_REFRESH_EVERY iterations, up to LATE_REFRESHES in all. On 24 random drags of 2-3 handle
# regions over the benchmark shapes, the worst pose after 30 iterations went from 7.8e-2 of the
# size off its minimum to 2.8e-2 (1.2e-1 to 1.5e-2 with the fold penalty). Without the step
# gate, a solve about to converge at its tenth iteration (the character's standard drag) paid a
# refresh and an iteration more. Solves with the area constraint already refresh up to
# NEWTON_STEPS_WITH_AREA times while steps are large; late refreshes on top kept the "B" turned
# by 90 degrees from converging (30 iterations instead of 20).
LATE_REFRESH_FROM = 10
LATE_REFRESH_EVERY = 3
LATE_REFRESHES = 12
LATE_UNTIL = 1e-3
# Up to this many points the solve starts from the as-similar-as-possible pose; above, from the
# pose of a coarse copy of the shape (_CoarseStart), which is also the two-grid's coarse level.
COARSE_START_POINTS = 3000
# Interior points of the two-grid's coarse copy below COARSE_START_POINTS (with its boundary
# resampled to the same spacing: 160-356 points in all on the benchmark shapes). 30 took up to
# 20 iterations on the benchmark drags, 120 made each refresh dearer for the same iterations.
COARSE_INTERIOR = 60
# Outline detail the coarse copy keeps, in units of its spacing. Small curved holes near a drag
# (the character's eyes) need it: at 0.02, their 16-point coarse rings left that drag at 14
# iterations; at 0.005, 10 (coarse copy 356 points instead of 235). Polygonal outlines (the
# traced horse, glyphs) simplify the same either way.
COARSE_DETAIL = 0.005
# A graph whose coarse copy would not be this many times smaller is its own coarse level: the
# two-grid would cost more than the Newton matrix it approximates.
COARSE_RATIO = 2
# Above this many points the two-grid's coarse graph (a few hundred points) is too coarse to
# help: on 15,000- and 55,000-point horses its solves reached no lower energy than the paper's
# matrix alone in the same iterations, at 1.3x the time. Such graphs iterate the paper's
# matrix from the pose of the coarse copy.
TWO_GRID_MAX_POINTS = 10000
# The area constraint's curvature is not in the Newton matrix (adding it makes the matrix
# indefinite), so constrained solves lean on more Newton steps.
NEWTON_STEPS_WITH_AREA = 12
# Coarse copies kept for graphs seen lately (see _coarse_copy).
_COARSE_COPIES_KEPT = 8
_COARSE_COPIES = {}
# Curvature pairs kept by L-BFGS. Without the fold penalty a solve rarely keeps more than 8
# (refreshes clear them); with it, 8 left the character's standard drag at the 30-iteration cap
# and 16 converges in 17.
HISTORY = 16
# The area constraint is met to this fraction of the rest area (rounding in the shoelace sum of a
# 12,000-point boundary alone is 1e-12); reaching it from the start takes at most PROJECTION_STEPS
# steps (one, unless the start is far from the rest area).
AREA_TOLERANCE = 1e-10
ROUNDING = 1e-13
PROJECTION_STEPS = 50
# Armijo sufficient-decrease constant and the most halvings the line search tries.
ARMIJO = 1e-4
MAX_HALVINGS = 30


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
        Numeric refactorisations this solve made of the matrix that follows the pose: the
        two-grid's coarse Newton matrix by default, the whole Newton matrix with
        ``newton=True``. The shape's own factor (``A_f^T A_f``) is never refactorised.
    """

    positions: np.ndarray
    iterations: int = 0
    energies: list = field(default_factory=list)
    converged: bool = False
    factorizations: int = 0


class _AreaConstraint:
    """Signed area of all boundary loops, a quadratic form in the stacked free coordinates.

    With all coordinates stacked ``p = [x; y]`` the shoelace sum is ``area = p^T Q p / 2`` for a
    constant sparse ``Q``. Splitting ``p`` into free (``v``) and fixed (``c``) parts gives
    ``area(v) = v^T Q_ff v / 2 + v . (Q_fc c) + c^T Q_cc c / 2`` and ``d area / dv = Q_ff v + Q_fc c``.
    """

    def __init__(self, graph, free, fixed):
        n = graph.n
        here = graph.boundary
        after = np.concatenate([np.roll(loop, -1) for loop in graph.boundary_loops])
        half = np.full(len(here), 0.5)
        # x_here * y_after / 2 - x_after * y_here / 2, symmetrised.
        shoelace = coo_matrix((np.concatenate([half, -half]),
                               (np.concatenate([here, after]), np.concatenate([n + after, n + here]))),
                              shape=(2 * n, 2 * n)).tocsr()
        shoelace = (shoelace + shoelace.T).tocsr()
        stacked_free = np.concatenate([free, n + free])
        stacked_fixed = np.concatenate([fixed, n + fixed])
        rows_free = shoelace[stacked_free]
        self._free_free = rows_free[:, stacked_free].tocsr()
        self._free_fixed = rows_free[:, stacked_fixed].tocsr()
        self._fixed_fixed = shoelace[stacked_fixed][:, stacked_fixed].tocsr()
        self._free_free_magnitude = abs(self._free_free)
        self._fixed_magnitude = (np.zeros(len(stacked_free)), 0.0)
        centred = graph.points - box_centre(graph.points)
        rest = np.concatenate([centred[:, 0], centred[:, 1]])
        self.rest = 0.5 * float(rest @ (shoelace @ rest))
        self._linear = np.zeros(len(stacked_free))
        self._constant = 0.0

    def hold(self, fixed_coordinates):
        """Take the fixed points' stacked coordinates ``(2 c,)`` for the solve that follows."""
        self._linear = self._free_fixed @ fixed_coordinates
        self._constant = 0.5 * float(fixed_coordinates @ (self._fixed_fixed @ fixed_coordinates))
        magnitude = np.abs(fixed_coordinates)
        self._fixed_magnitude = (abs(self._free_fixed) @ magnitude,
                                 0.5 * float(magnitude @ (abs(self._fixed_fixed) @ magnitude)))

    def met(self, v, rounding=False):
        """Whether the area at ``v`` is the rest area to ``AREA_TOLERANCE``; with ``rounding``,
        or to the rounding of its own sum, when that is larger (at a pose so large that this is
        all float64 can tell: a start after an extreme drag of a needle-spiked shape reached
        5,000 times the shape's size)."""
        bound = AREA_TOLERANCE * abs(self.rest)
        if rounding:
            linear, constant = self._fixed_magnitude
            magnitude = np.abs(v)
            terms = 0.5 * float(magnitude @ (self._free_free_magnitude @ magnitude))
            terms += float(linear @ magnitude) + constant
            bound = max(bound, ROUNDING * terms)
        return abs(self.area(v) - self.rest) <= bound

    def area(self, v):
        return 0.5 * float(v @ (self._free_free @ v)) + float(self._linear @ v) + self._constant

    def jacobian(self, v):
        """d area / d v, stacked ``(2 f,)``."""
        return self._free_free @ v + self._linear

    def restore(self, v, direction):
        """Move ``v`` along ``direction`` so its area is the rest area; False if it cannot."""
        a = 0.5 * float(direction @ (self._free_free @ direction))
        b = float(self.jacobian(v) @ direction)
        c = self.area(v) - self.rest
        if abs(a) <= 1e-14 * abs(b):
            if b == 0.0:
                return c == 0.0
            mu = -c / b
        else:
            discriminant = b * b - 4.0 * a * c
            if discriminant < 0.0:
                return False
            root = np.sqrt(discriminant)
            # The smaller correction; written to avoid cancellation.
            q = -0.5 * (b + np.copysign(root, b))
            candidates = [q / a, c / q] if q != 0.0 else [0.0]
            mu = min(candidates, key=abs)
        v += mu * direction
        return True

    def project(self, v, directions):
        """Move ``v`` (in place) to the rest area; False if ``PROJECTION_STEPS`` do not get there
        (or to the rounding of the area's sum, see :meth:`met`).

        ``directions(jacobian)`` gives the direction to move along (the solver's ``H^-1 J``). When
        the area cannot reach the rest area along it (a start far from it, after an extreme
        drag: the area's curvature along the line turns it back first), the area's own gradient
        is tried, and failing that the step goes along the gradient to where the area is nearest
        the rest area, and a new direction is taken from there.
        """
        for _ in range(PROJECTION_STEPS):
            if self.met(v):
                return True
            jacobian = self.jacobian(v)
            if self.restore(v, directions(jacobian)) or self.restore(v, jacobian):
                continue
            # Along the area's own gradient, go to where the area is nearest the rest area.
            curvature = float(jacobian @ (self._free_free @ jacobian))
            slope = float(jacobian @ jacobian)
            if curvature == 0.0 or slope == 0.0:
                return False
            v -= (slope / curvature) * jacobian
        return self.met(v, rounding=True)


class Deformer:
    """The paper's deformer for one graph and one set of handles.

    Parameters
    ----------
    graph : solver.Graph
    handles : (h,) array_like of int
        Indices of graph points that are moved to targets. A connected part of the graph with
        no handle stays at rest.
    weights : dict, optional
        Weights of the energy terms ``"laplacian"``, ``"mvc"`` and ``"edge"``.
    preserve_area : bool
        Keep the total area (islands minus holes) equal to the rest area.
    newton : bool, optional
        ``None`` (default): L-BFGS with the two-grid preconditioner of :mod:`solver.two_grid`.
        Its fine factor, ``A_f^T A_f``, is made here and never again, so moving handles only
        changes right-hand sides of the shape's system; what follows the pose is a Newton
        matrix on a coarse copy of the shape (a few hundred points), refactorised at most
        ``NEWTON_STEPS`` times per solve (every few iterations more in a solve that runs past
        ``LATE_REFRESH_FROM``). Up to ``COARSE_START_POINTS`` points a solve starts from the
        as-similar-as-possible pose; above, from the coarse copy's pose, and above
        ``TWO_GRID_MAX_POINTS`` it iterates ``A_f^T A_f`` alone. A graph too small to have a
        coarser copy is its own coarse level (the Newton matrix below).
        ``True``: projected Newton steps on the whole graph, as many as the refreshes above,
        each a numeric refactorisation (the symbolic analysis is shared), then L-BFGS.
        ``False``: the paper's way, L-BFGS on ``A_f^T A_f`` alone from the pose of a coarse
        copy of the shape; cheapest per iteration, slow to turn free limbs.
    prevent_flips : bool
        The paper's energy admits poses with folded (inverted) triangles in large bends (where a
        dragged region meets the rest, typically). With this on, triangles squeezed below a
        tenth of their rest area are pushed back open by a penalty (:mod:`solver.folds`); poses
        that squeeze none that far are the paper's minima unchanged.

    Raises
    ------
    ValueError
        Handles out of range or repeated, bad weights, or ``preserve_area`` with no boundary point
        free to move (all are handles or on islands without handles): the area would be fixed.
    """

    def __init__(self, graph, handles, weights=None, preserve_area=False, newton=None,
                 prevent_flips=False):
        self.graph = graph
        self.prevent_flips = bool(prevent_flips)
        self._folds = None
        handles = np.asarray(handles, dtype=np.int64).ravel()
        if len(handles) and (handles.min() < 0 or handles.max() >= graph.n):
            raise ValueError(f"handle indices must be in [0, {graph.n}), got {handles.min()}..{handles.max()}")
        if len(np.unique(handles)) != len(handles):
            raise ValueError("a point is given as a handle twice")
        self.handles = handles
        self.energy = Energy(graph, weights)
        self._size = graph.size  # a bounding-box measure: once, not per solve
        self.preserve_area = bool(preserve_area)

        fixed = np.zeros(graph.n, dtype=bool)
        fixed[handles] = True
        labels = graph.components()
        anchored = np.zeros(labels.max() + 1, dtype=bool)
        anchored[labels[handles]] = True
        self._resting = ~anchored[labels]  # islands without handles stay put
        fixed |= self._resting
        self.free = np.flatnonzero(~fixed)
        self._fixed = np.flatnonzero(fixed)

        if len(self.free):
            # The solve iterates on the free points' coordinates stacked [x; y] (length 2 f) and
            # keeps A V coordinate-major (2, r): A V = A_c c + [A_f 0; 0 A_f] v, flattened.
            matrix = self.energy.matrix.tocsc()
            free_columns = matrix[:, self.free]
            self._free_block = block_diag([free_columns, free_columns], format="csr")
            self._free_block_transpose = self._free_block.T.tocsr()
            self._fixed_columns = matrix[:, self._fixed].tocsr()
            weight = np.asarray(abs(free_columns).sum(axis=0)).ravel()
            if np.any(weight == 0.0):
                raise ValueError(
                    f"with these weights {int((weight == 0).sum())} points are in no energy term and "
                    "nothing decides where they go; give 'mvc' or 'edge' a positive weight")
            if self.prevent_flips:
                self._folds = FoldPenalty(graph, self.free, self._fixed)
            self._coarse = None
            if newton or (newton is None and graph.n <= COARSE_START_POINTS):
                self._hessian = self._newton_or_two_grid(newton)
            else:
                self._coarse = _CoarseStart(graph, handles, weights, preserve_area, self.prevent_flips)
                if newton is None and graph.n <= TWO_GRID_MAX_POINTS:
                    self._hessian = TwoGrid(self.energy, self.free, self._coarse.binding.weights[self.free],
                                            None if self._folds is None else graph.triangles)
                else:
                    self._hessian = PaperMatrix(self.energy, self.free)
        if len(self.free) and self._coarse is None:
            # The similarity system for the start (see energy.similarity_rows), x and y stacked.
            similarity = similarity_rows(graph.points, graph.triangles).tocsc()
            stacked_free = np.concatenate([self.free, graph.n + self.free])
            fixed_points = np.flatnonzero(fixed)
            self._stacked_fixed = np.concatenate([fixed_points, graph.n + fixed_points])
            similarity_free = similarity[:, stacked_free]
            self._similarity_fixed = similarity[:, self._stacked_fixed].tocsr()
            self._similarity_free_transpose = similarity_free.T.tocsr()
            normal = (self._similarity_free_transpose @ similarity_free).tocsc()
            # Free points touching no triangle would make this singular; a tiny pull towards
            # their rest positions keeps them there and changes nothing else measurably.
            tiny = 1e-12 * _diagonal_scale(normal)
            normal = normal + tiny * identity(normal.shape[0], format="csc")
            # Solved about the rest shape's centre: the pull is what settles turns and scales the
            # handles leave open (a single handle point), and far from the origin its rounding
            # turned a shape 1e6 times smaller than its offset by more than its size.
            self._similarity_origin = box_centre(graph.points)
            self._similarity_rest_pull = tiny * (graph.points[self.free] - self._similarity_origin).T.ravel()
            self._similarity_factor = qdldl.Solver(triu(normal, format="csc"), upper=True)
        self._area = _AreaConstraint(graph, self.free, self._fixed) if self.preserve_area else None
        if self._area is not None and not np.isin(graph.boundary, self.free).any():
            raise ValueError("preserve_area needs a boundary point that can move: every boundary point is a "
                             "handle or lies on an island without handles, which stays at rest")

    def _newton_or_two_grid(self, newton):
        """The two-grid on a coarse copy of about ``COARSE_INTERIOR`` interior points, or the
        Newton matrix with ``newton=True`` or on a graph with no copy ``COARSE_RATIO`` times
        coarser (it is then as small as a coarse level)."""
        graph = self.graph
        folds = None if self._folds is None else graph.triangles
        if not newton and graph.n >= COARSE_RATIO * COARSE_INTERIOR:
            copy = _coarse_copy(graph, COARSE_INTERIOR)
            if copy is not None and COARSE_RATIO * copy[0].n <= graph.n:
                return TwoGrid(self.energy, self.free, copy[1].weights[self.free], folds)
        return Hessian(self.energy, self.free, folds)

    def _start(self, targets, initial):
        rest = self.graph.points
        if initial is not None:
            positions = np.array(initial, dtype=np.float64)
            if positions.shape != rest.shape:
                raise ValueError(f"initial must have shape {rest.shape}, got {positions.shape}")
            if not np.all(np.isfinite(positions)):
                raise ValueError("initial has non-finite coordinates (NaN or inf)")
        else:  # every free point is set below; fixed ones are handles or resting islands
            positions = rest.copy()
        positions[self._resting] = rest[self._resting]
        positions[self.handles] = targets
        if initial is None and len(self.free):
            if self._coarse is not None:
                positions[self.free] = self._coarse.start(targets)[self.free]
            else:
                positions = self._similar_start(positions)
        return positions

    def _similar_start(self, positions):
        """The as-similar-as-possible pose for the current fixed points (one linear solve)."""
        origin = self._similarity_origin
        stacked = np.concatenate([positions[:, 0] - origin[0], positions[:, 1] - origin[1]])
        rhs = self._similarity_rest_pull - self._similarity_free_transpose @ (
            self._similarity_fixed @ stacked[self._stacked_fixed])
        free = self._similarity_factor.solve(rhs)
        k = len(self.free)
        positions = positions.copy()
        positions[self.free, 0] = free[:k] + origin[0]
        positions[self.free, 1] = free[k:] + origin[1]
        return positions

    def solve(self, targets, max_iterations=None, tolerance=None, initial=None):
        """Deform so that ``handles[i]`` lands on ``targets[i]``.

        Parameters
        ----------
        targets : (h, 2) array_like
            Target of each handle, in the order given to the constructor.
        max_iterations : int, optional
            Default ``DEFAULT_MAX_ITERATIONS``.
        tolerance : float, optional
            Stop once the next step would move no point more than ``tolerance * graph.size``.
            ``0.0`` runs exactly ``max_iterations``. Default ``DEFAULT_TOLERANCE``.
        initial : (n, 2) array_like, optional
            Warm start. By default the as-similar-as-possible pose for the targets (for large
            graphs, the pose of a coarse copy of the shape), so the result depends on the
            targets alone.

        Returns
        -------
        Solution

        Raises
        ------
        ValueError
            Targets of the wrong shape or not finite; with ``preserve_area``, no pose with the rest
            area found near the start.
        """
        targets = np.asarray(targets, dtype=np.float64)
        if targets.shape != (len(self.handles), 2):
            raise ValueError(f"targets must have shape ({len(self.handles)}, 2), got {targets.shape}")
        if not np.all(np.isfinite(targets)):
            raise ValueError("targets have non-finite coordinates (NaN or inf)")
        max_iterations = DEFAULT_MAX_ITERATIONS if max_iterations is None else int(max_iterations)
        tolerance = DEFAULT_TOLERANCE if tolerance is None else float(tolerance)
        if max_iterations < 0 or tolerance < 0:
            raise ValueError("max_iterations and tolerance must be >= 0")

        positions = self._start(targets, initial)
        if len(self.free) == 0:
            return Solution(positions, 0, [], True)
        # The energy ignores translation, but rounding in the area (a sum of products of
        # coordinates) does not: a shape dragged 100 times its size away kept its area to only
        # 3e-6. So iterate on coordinates centred on the start pose.
        origin = box_centre(positions)
        local = positions - origin
        fixed = local[self._fixed]
        fixed_rows = (self._fixed_columns @ fixed).T.ravel()
        if self._area is not None:
            self._area.hold(fixed.T.ravel())
        if self._folds is not None:
            self._folds.hold(fixed)
        try:
            solution = self._iterate(local[self.free].T.ravel(), fixed_rows, max_iterations, tolerance)
        except RuntimeError as error:  # qdldl: a matrix that is not positive definite
            raise ValueError(f"the deformation system is singular ({error}): the weights or handles "
                             "leave part of the shape free to move without changing the energy") from None
        positions[self.free] = solution.positions.reshape(2, -1).T + origin
        solution.positions = positions
        return solution

    def _evaluate(self, v, fixed_rows):
        """Energy, half its gradient ``(2 f,)``, and the pose (rows ``A V`` ``(2, r)`` and the
        local fit) at free coordinates ``v``."""
        rows = self._free_block @ v
        rows += fixed_rows
        rows = rows.reshape(2, -1)
        residual, fit = self.energy.local_step(rows)
        residual = residual.ravel()
        energy, gradient = float(residual @ residual), self._free_block_transpose @ residual
        if self._folds is not None:
            fold_energy, fold_gradient = self._folds.evaluate(v)
            if fold_gradient is not None:
                energy, gradient = energy + fold_energy, gradient + fold_gradient
        return energy, gradient, (rows, fit)

    def _factorize(self, v, pose):
        rows, fit = pose
        self._hessian.factorize(rows, None if self._folds is None else self._folds.terms(v), fit)

    def _iterate(self, v, fixed_rows, max_iterations, tolerance):
        """Minimise over the stacked free coordinates ``v`` (2 f,)."""
        size = self._size
        step_limit = tolerance * size
        area = self._area
        direction = None
        hessian = self._hessian
        newton_limit = NEWTON_STEPS if area is None else NEWTON_STEPS_WITH_AREA
        if isinstance(hessian, PaperMatrix):
            newton_limit = 0
        if area is not None:
            rows = (fixed_rows + self._free_block @ v).reshape(2, -1)
            self._factorize(v, (rows, None))
            if not area.project(v, hessian.solve):
                raise ValueError(f"preserve_area: found no pose with the rest area near the start for these "
                                 f"targets (the nearest was {area.area(v) / area.rest - 1.0:.2g} off it)")
            jacobian = area.jacobian(v)  # kept with direction: both change only with v
            direction = hessian.solve(jacobian)
        energy, gradient, pose = self._evaluate(v, fixed_rows)  # gradient: half the true one
        if area is None:
            self._factorize(v, pose)
        newton_steps = 1 if newton_limit else 0
        last_refresh = 0
        fresh = False
        history = deque(maxlen=HISTORY)
        solution = Solution(v)
        for _ in range(max_iterations):
            search_gradient = gradient
            if area is not None:
                # Along the constraint the energy's curvature is the Lagrangian's.
                multiplier = _multiplier(gradient, jacobian, direction)
                search_gradient = gradient - multiplier * jacobian
            step = -self._two_loop(search_gradient, history)
            if area is not None:
                step = _tangent(step, jacobian, direction)
            slope = 2.0 * float(gradient @ step)
            if slope >= 0.0 and history:
                history.clear()
                step = -hessian.solve(search_gradient)
                if area is not None:
                    step = _tangent(step, jacobian, direction)
                slope = 2.0 * float(gradient @ step)
            # Converged when the proposed step moves no point more than the tolerance: the pose
            # is then that close to the minimum the model sees. (A step the line search shortened
            # would say nothing of the kind; checking before the search also saves an energy
            # evaluation.)
            if tolerance > 0.0 and not fresh and float(np.abs(step).max()) <= step_limit:
                solution.converged = True
                break
            moved = self._line_search(v, fixed_rows, energy, step, slope, direction)
            if moved is None:
                # No decrease is possible: this is a minimum to rounding.
                solution.iterations += 1
                solution.energies.append(energy)
                if tolerance > 0.0:
                    solution.converged = True
                    break
                continue
            new_v, new_energy, new_gradient, pose = moved
            s = new_v - v
            largest = float(np.abs(s).max())
            solution.iterations += 1
            solution.energies.append(new_energy)
            early = newton_steps < newton_limit and largest > NEWTON_UNTIL * size
            late = (newton_limit > 0 and area is None and newton_steps < LATE_REFRESHES
                    and solution.iterations >= LATE_REFRESH_FROM
                    and solution.iterations - last_refresh >= LATE_REFRESH_EVERY
                    and largest > LATE_UNTIL * size)
            refactor = early or late
            # The first step after a late refresh is the bare preconditioner's, short in a flat
            # valley however far the minimum: it says nothing of convergence.
            fresh = late and not early
            if refactor:
                self._factorize(new_v, pose)
                newton_steps += 1
                last_refresh = solution.iterations
                history.clear()
            if area is not None:
                new_jacobian = area.jacobian(new_v)
                new_direction = hessian.solve(new_jacobian)
            if not refactor:
                y = new_gradient - gradient
                if area is not None:
                    multiplier = _multiplier(new_gradient, new_jacobian, new_direction)
                    y -= multiplier * (new_jacobian - jacobian)
                sy = float(s @ y)
                if sy > 1e-12 * np.sqrt(float(s @ s) * float(y @ y)):
                    history.append((s, y, 1.0 / sy))
            v, energy, gradient = new_v, new_energy, new_gradient
            if area is not None:
                direction, jacobian = new_direction, new_jacobian
        solution.positions = v
        solution.factorizations = newton_steps
        return solution

    def _two_loop(self, gradient, history):
        """L-BFGS inverse-Hessian product with the last factor as the initial Hessian."""
        q = gradient.copy()
        coefficients = []
        for s, y, rho in reversed(history):
            a = rho * float(s @ q)
            q -= a * y
            coefficients.append(a)
        z = self._hessian.solve(q)
        for (s, y, rho), a in zip(history, reversed(coefficients)):
            z += (a - rho * float(y @ z)) * s
        return z

    def _line_search(self, v, fixed_rows, energy, step, slope, direction):
        """Backtrack from the full step until the energy decreases enough (Armijo)."""
        if slope >= 0.0:
            return None
        alpha = 1.0
        for _ in range(MAX_HALVINGS):
            trial = v + alpha * step
            if self._area is None or self._area.restore(trial, direction):
                trial_energy, gradient, pose = self._evaluate(trial, fixed_rows)
                if trial_energy <= energy + ARMIJO * alpha * slope:
                    return trial, trial_energy, gradient, pose
            alpha *= 0.5
        return None


class _CoarseStart:
    """The pose of a coarse copy of the shape, carried to a large graph's points: the start of
    every solve above ``COARSE_START_POINTS``.

    A graph of a few hundred points built from the same boundary solves with Newton steps in
    milliseconds and gets the turns of whole limbs right; the fine iterations then fix local
    detail. Starting there also keeps a dense graph's pose close to the coarse one's: from the
    as-similar-as-possible start, a 9,000-point horse turning its head settled in a minimum
    with 9% more energy, 3% of its size away from the coarse pose.
    """

    def __init__(self, graph, handles, weights, preserve_area, prevent_flips):
        # The default spacing: a few hundred points, whatever the fine graph's density.
        self.graph, self.binding = _coarse_copy(graph)
        rest = graph.points[handles]
        # Each coarse point nearest a handle point follows that handle point's target.
        _, nearest = cKDTree(self.graph.points).query(rest)
        self.coarse_handles, self.first = np.unique(nearest, return_index=True)
        self.offset = self.graph.points[self.coarse_handles] - rest[self.first]
        self.deformer = Deformer(self.graph, self.coarse_handles, weights, preserve_area, newton=True,
                                 prevent_flips=prevent_flips)

    def start(self, targets):
        coarse = self.deformer.solve(targets[self.first] + self.offset)
        return self.binding.apply(coarse.positions)


def _coarse_copy(graph, interior=None):
    """A coarse copy of ``graph``'s shape and the binding of ``graph``'s points to it.

    With ``interior``, about that many interior points (:func:`~solver.outline.outline_graph`,
    outline kept to ``COARSE_DETAIL``) and None if the outline will not make one; without, the
    default spacing (:func:`~solver.graph.build_graph`). The copy depends on the graph alone,
    while a Deformer is rebuilt for every change of handles or weights (the add-on does so on
    every such edit), so the last few are kept, keyed by the graph's points and loops.
    """
    loops = graph.boundary_loops
    digest = hashlib.blake2b(graph.points.tobytes(), digest_size=16)
    digest.update(np.array([len(loop) for loop in loops], dtype=np.int64).tobytes())
    digest.update(np.concatenate(loops).astype(np.int64).tobytes())
    key = (digest.digest(), interior)
    if key not in _COARSE_COPIES:
        rings = [graph.points[loop] for loop in loops]
        if interior is None:
            coarse = build_graph(rings)
        else:
            try:
                coarse = outline_graph(rings, interior, COARSE_DETAIL)
            except ValueError:  # an outline the coarse copy cannot be built from
                coarse = None
        while len(_COARSE_COPIES) >= _COARSE_COPIES_KEPT:
            del _COARSE_COPIES[next(iter(_COARSE_COPIES))]
        _COARSE_COPIES[key] = None if coarse is None else (coarse, bind(coarse, graph.points))
    return _COARSE_COPIES[key]


def _multiplier(gradient, jacobian, direction):
    """Least-squares Lagrange multiplier of the area constraint in the metric of H
    (``direction = H^-1 jacobian``)."""
    along = float(jacobian @ direction)
    if along <= 0.0:
        return 0.0
    return float(gradient @ direction) / along


def _tangent(step, jacobian, direction):
    """Remove the part of a step that changes the area to first order."""
    along = float(jacobian @ direction)
    if along <= 0.0:
        return step
    return step - direction * (float(jacobian @ step) / along)


def _diagonal_scale(matrix):
    diagonal = matrix.diagonal()
    return float(diagonal.max()) if len(diagonal) else 1.0
