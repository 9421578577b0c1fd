"""Every knob of a solve, in one place: :class:`Options`.

The defaults are what the measurements in ``docs/solver_options.md`` chose, with the commands
that repeat them; a caller who wants other trade-offs passes its own ``Options`` to
:class:`solver.Deformer`. Knobs of the energy itself (the three term weights, the area
constraint, the fold penalty switch) stay arguments of the Deformer: they change what is
minimised, these change how.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, fields

import numpy as np

__all__ = ["Options"]


@dataclass(frozen=True)
class Options:
    """How :class:`solver.Deformer` builds its solver and runs a solve.

    Attributes
    ----------
    max_iterations : int
        Iterations per solve unless :meth:`~solver.Deformer.solve` is given others.
    tolerance : float
        Stop once the next step would move no point more than this fraction of the shape's
        size (``0.0`` runs every iteration).
    history : int
        Curvature pairs L-BFGS keeps.
    armijo : float
        Sufficient-decrease constant of the line searches.
    wolfe_curvature : float
        Newton's line search stops where the slope along the step has fallen to this fraction
        of its first value (the strong Wolfe curvature condition; 0.9 is the usual choice for
        Newton and quasi-Newton steps).
    newton_max_points : int
        Graphs up to this many points are solved by Newton's method, refactorising the Newton
        matrix at every iterate; larger ones by Newton's method with its system solved by
        conjugate gradients over the two-grid preconditioner (:mod:`solver.krylov`), or, with
        the area constraint or ``newton=False``, by L-BFGS over a preconditioner that is
        refactorised rarely or never.
    max_halvings : int
        Trial steps a line search makes (halvings when backtracking; the Wolfe search may also
        lengthen the step) before it calls the pose a minimum to rounding.
    refreshes : int
        L-BFGS only (the area constraint on graphs above ``newton_max_points``): refreshes of
        the two-grid's coarse Newton matrix at most per solve, made while steps exceed
        ``refresh_until`` times the size; L-BFGS reuses the last one afterwards.
    refresh_until : float
        See ``refreshes``.
    coarse_start_points : int
        Above this many graph points the coarse copy a solve may start from (and the two-grid's
        coarse level) is a graph at the default spacing; below, an outline copy of about
        ``coarse_interior`` interior points. Either way the solve starts from the lower-energy
        of the coarse copy's pose and the as-similar-as-possible pose.
    coarse_interior : int
        Interior points of the outline copy below ``coarse_start_points``.
    coarse_detail : float
        Outline detail that copy keeps, in units of its spacing.
    coarse_ratio : float
        A graph whose coarse copy would not be this many times smaller is its own coarse
        level (the whole Newton matrix).
    two_grid_max_points : int
        Above this many points the paper's matrix alone is iterated (a coarse copy of a few
        hundred points is then too coarse to help).
    max_fold_terms : int
        Fold-penalty terms (the stiffest squeezed triangles) the two-grid's smoother takes
        in under L-BFGS, each one back-substitution per refresh (conjugate gradients take
        none: their preconditioner need not lie above the matrix).
    fold_threshold : float
        With ``prevent_flips``: triangles squeezed below this fraction of their rest area are
        pushed back open (:mod:`solver.folds`).
    fold_weight : float
        The fold penalty's push at zero area, relative to the paper's terms: how fast a
        triangle's term falls, per unit of area ratio and of rest area, as it reopens. With the
        density normalisation a graph denser than the default spacing multiplies it by the
        square of the spacings' ratio, so each triangle is held open as firmly as one at the
        default spacing.
    fold_weight_at_handles : float
        Triangles with a corner held by a handle, where a handle region's rigid motion squeezes
        the free points beside it hardest, are held open at least this many times as firmly as
        ``fold_weight`` holds a triangle at the default spacing (on denser graphs, whose
        weight the spacing already raises more, nothing changes).
    sliver_area : float
        Area per squared longest edge below which a triangle counts as a sliver, whose fold
        stiffness is bounded.
    """

    max_iterations: int = 30
    tolerance: float = 1e-4
    history: int = 16
    armijo: float = 1e-4
    wolfe_curvature: float = 0.9
    newton_max_points: int = 3000
    max_halvings: int = 30
    refreshes: int = 12
    refresh_until: float = 1e-2
    coarse_start_points: int = 3000
    coarse_interior: int = 60
    coarse_detail: float = 0.005
    coarse_ratio: float = 2.0
    two_grid_max_points: int = 10000
    max_fold_terms: int = 32
    fold_threshold: float = 0.4
    fold_weight: float = 20.0
    fold_weight_at_handles: float = 3.0
    sliver_area: float = 0.05

    def __post_init__(self):
        for item in fields(self):
            value = getattr(self, item.name)
            # numpy's numbers too; a whole float is taken for an integer field (30.0 passed
            # here, then failed inside the solve with Python's own TypeError).
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
                raise ValueError(f"Options.{item.name} must be a number, got {value!r}")
            if item.type == "int" and int(value) != value:
                raise ValueError(f"Options.{item.name} must be a whole number, got {value!r}")
            if not value >= 0 or value == float("inf"):
                raise ValueError(f"Options.{item.name} must be finite and >= 0, got {value!r}")
            object.__setattr__(self, item.name, int(value) if item.type == "int" else float(value))
