"""How the energy is minimised: Newton's method (:func:`newton`), or L-BFGS over a
preconditioner (:func:`minimise`).

:func:`newton` refreshes its matrix at every iterate, :class:`~solver.hessian.NewtonMatrix`
(factorised: exact where positive definite, else halfway to its projection or
projected) or, for large graphs,
:class:`~solver.krylov.KrylovNewton` (the exact Hessian, its system solved by preconditioned
conjugate gradients to a relative residual ``min(1/2, sqrt(|g| / |g_0|))``, Eisenstat and
Walker's forcing term), and searches along the step for the strong Wolfe conditions: the step
may grow as well as shrink, since away from a minimum the projected matrix overestimates the
energy's curvature and a truncated step may fall short. Its only knobs are the line search's
two constants.

:func:`minimise`, L-BFGS, serves the area constraint on large graphs and the paper's matrix alone:
The preconditioner (:mod:`solver.preconditioner`) is L-BFGS's initial inverse Hessian; the
curvature pairs it keeps add what the preconditioner misses. Every accepted step lowers the
energy (Armijo). A preconditioner that follows the pose is refreshed there, which clears the
pairs, while steps are large (``Options.refreshes`` and ``Options.refresh_until``).

With the area constraint (:mod:`solver.area`) every step is projected onto the constraint's
tangent in the preconditioner's metric, the curvature pairs use the Lagrangian's gradient, and
each trial point is moved back onto the constraint exactly before its energy is measured.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from .area import multiplier, tangent

__all__ = ["Result", "minimise", "newton"]


@dataclass
class Result:
    """What :func:`minimise` reached.

    Attributes
    ----------
    v : (2 f,) float64 ndarray
        The free coordinates, stacked ``[x; y]``.
    iterations : int
    energies : list of float
        Energy after each iteration (never increasing).
    converged : bool
    refreshes : int
        Refreshes of the preconditioner, the one before the first iteration included.
    """

    v: np.ndarray
    iterations: int = 0
    energies: list = field(default_factory=list)
    converged: bool = False
    refreshes: int = 0


def newton(objective, matrix, v, options, size, max_iterations, tolerance, area=None):
    """Minimise ``objective`` by Newton's method from ``v``.

    With ``area`` the step is projected onto the constraint's tangent in the matrix's metric and
    each trial point moved back onto the constraint, so the line search only backtracks (Armijo).

    Parameters
    ----------
    objective : object
        As for :func:`minimise`; its ``refresh`` refactors ``matrix`` at every iterate.
    matrix : solver.preconditioner.NewtonSystem
    v : (2 f,) float64 ndarray
        The start, stacked ``[x; y]`` (moved in place onto the area constraint with ``area``).
    options : solver.Options
    size : float
        The shape's size: the tolerance is a fraction of it.
    max_iterations : int
    tolerance : float
        Stop once an exact Newton step (``matrix.exact``) would move no coordinate more than
        ``tolerance * size``; ``0.0`` runs every iteration.
    area : solver.area.AreaConstraint, optional

    Returns
    -------
    Result
    """
    step_limit = tolerance * size
    result = Result(v)
    if area is not None:
        _project_start(objective, matrix, area, v)
    energy, gradient, pose = objective.evaluate(v)  # gradient: half the true one
    first_norm = float(np.linalg.norm(gradient))
    for _ in range(max_iterations):
        norm = float(np.linalg.norm(gradient))
        forcing = min(0.5, np.sqrt(norm / first_norm)) if first_norm > 0.0 else 0.0
        step, jacobian, direction = _newton_step(objective, matrix, v, pose, gradient, area, forcing)
        result.refreshes += 1
        # A projected matrix is stiffer than the energy, and a truncated step stopped at negative
        # curvature, so their short steps say little of the distance to the minimum (in a flat
        # valley it may be far): only an exact step stops.
        if tolerance > 0.0 and float(np.abs(step).max()) <= step_limit and matrix.exact:
            result.converged = True
            break
        slope = 2.0 * float(gradient @ step)
        if area is None:
            moved = _wolfe_search(objective, options, v, energy, slope, step)
        else:
            moved = _line_search(objective, options, v, energy, step, slope, area, direction)
        result.iterations += 1
        if moved is None:  # no decrease is possible: a minimum to rounding
            result.energies.append(energy)
            result.converged = tolerance > 0.0
            if tolerance > 0.0:
                break
            continue
        v, energy, gradient, pose = moved
        result.energies.append(energy)
    result.v = v
    return result


def _project_start(objective, matrix, area, v):
    """Move the start ``v`` (in place) onto the area constraint along ``H^-1 J``, with the
    matrix refreshed at ``v``; ValueError when no pose with the rest area is found near it."""
    objective.refresh(v, None)
    if not area.project(v, matrix.solve):
        raise ValueError(f"preserve_area: found no pose with the rest area near the start for these "
                         f"targets (the nearest was {area.area(v) / area.rest - 1.0:.2g} off it)")


def _newton_step(objective, matrix, v, pose, gradient, area, forcing):
    """Refactor ``matrix`` at ``v`` and return the Newton step (projected onto the area
    constraint's tangent with ``area``), with the constraint's jacobian and ``H^-1 J`` (None
    without). ``forcing`` is the relative residual an iterative ``matrix`` may leave."""
    objective.refresh(v, pose)
    if area is None:
        return -matrix.solve(gradient, forcing), None, None
    jacobian = area.jacobian(v)
    direction = matrix.solve(jacobian)
    step = -matrix.solve(gradient - multiplier(gradient, jacobian, direction) * jacobian)
    return tangent(step, jacobian, direction), jacobian, direction


def _descent_step(preconditioner, gradient, history, area, jacobian, direction):
    """The quasi-Newton step from the history, or the preconditioner's own when that one does
    not descend (the history is then dropped); tangent to the area constraint when there is one.

    Returns
    -------
    step : (2 f,) ndarray
    slope : float
        The energy's derivative along ``step``.
    """
    search_gradient = gradient
    if area is not None:
        # Along the constraint the energy's curvature is the Lagrangian's.
        search_gradient = gradient - multiplier(gradient, jacobian, direction) * jacobian

    def along_constraint(step):
        return step if area is None else tangent(step, jacobian, direction)

    step = along_constraint(-_two_loop(preconditioner, search_gradient, history))
    slope = 2.0 * float(gradient @ step)
    if slope >= 0.0 and history:
        history.clear()
        step = along_constraint(-preconditioner.solve(search_gradient))
        slope = 2.0 * float(gradient @ step)
    return step, slope


def _remember(history, s, y):
    """Keep the pair (s, y) unless its curvature is not positive."""
    sy = float(s @ y)
    if sy > 1e-12 * np.sqrt(float(s @ s) * float(y @ y)):
        history.append((s, y, 1.0 / sy))


def minimise(objective, preconditioner, v, options, size, max_iterations, tolerance, area=None):
    """Minimise ``objective`` over the stacked free coordinates, starting from ``v``.

    Parameters
    ----------
    objective : object
        ``evaluate(v) -> (energy, half_gradient (2 f,), pose)`` and ``refresh(v, pose)``, which
        refactors ``preconditioner`` at that pose.
    preconditioner : solver.preconditioner.Preconditioner
    v : (2 f,) float64 ndarray
        The start, modified in place by the area projection.
    options : solver.Options
    size : float
        The shape's size: tolerances and refresh thresholds are fractions of it.
    max_iterations : int
    tolerance : float
        Stop once the next step would move no coordinate more than ``tolerance * size``;
        ``0.0`` runs every iteration.
    area : solver.area.AreaConstraint, optional
        Holding the fixed points of this solve (:meth:`~solver.area.AreaConstraint.hold`).

    Returns
    -------
    Result

    Raises
    ------
    ValueError
        With ``area``: no pose with the rest area found near the start.
    """
    step_limit = tolerance * size
    limit = options.refreshes if preconditioner.follows_pose else 0
    result = Result(v)
    direction = jacobian = None
    if area is not None:
        _project_start(objective, preconditioner, area, v)
        jacobian = area.jacobian(v)  # kept with direction: both change only with v
        direction = preconditioner.solve(jacobian)
    energy, gradient, pose = objective.evaluate(v)  # gradient: half the true one
    if area is None:
        objective.refresh(v, pose)
    result.refreshes = 1 if limit else 0
    history = deque(maxlen=options.history)
    for _ in range(max_iterations):
        step, slope = _descent_step(preconditioner, gradient, history, area, jacobian, direction)
        # Converged when the proposed step moves no point more than the tolerance: the pose is
        # then that close to the minimum the model sees. (A step the line search shortened
        # would say nothing of the kind; checking before the search also saves an evaluation.)
        if tolerance > 0.0 and float(np.abs(step).max()) <= step_limit:
            result.converged = True
            break
        moved = _line_search(objective, options, v, energy, step, slope, area, direction)
        result.iterations += 1
        if moved is None:  # no decrease is possible: a minimum to rounding
            result.energies.append(energy)
            if tolerance > 0.0:
                result.converged = True
                break
            continue
        new_v, new_energy, new_gradient, pose = moved
        s = new_v - v
        largest = float(np.abs(s).max())
        result.energies.append(new_energy)
        refresh = result.refreshes < limit and largest > options.refresh_until * size
        if refresh:
            objective.refresh(new_v, pose)
            result.refreshes += 1
            history.clear()
        if area is not None:
            new_jacobian = area.jacobian(new_v)
            new_direction = preconditioner.solve(new_jacobian)
        if not refresh:
            y = new_gradient - gradient
            if area is not None:
                y -= multiplier(new_gradient, new_jacobian, new_direction) * (new_jacobian - jacobian)
            _remember(history, s, y)
        v, energy, gradient = new_v, new_energy, new_gradient
        if area is not None:
            direction, jacobian = new_direction, new_jacobian
    result.v = v
    return result


def _two_loop(preconditioner, gradient, history):
    """L-BFGS inverse-Hessian product with the preconditioner as the initial inverse Hessian."""
    q = gradient.copy()
    coefficients = []
    for s, y, rho in reversed(history):
        a = rho * float(s @ q)
        q -= a * y
        coefficients.append(a)
    z = preconditioner.solve(q)
    for (s, y, rho), a in zip(history, reversed(coefficients)):
        z += (a - rho * float(y @ z)) * s
    return z


def _line_search(objective, options, v, energy, step, slope, area, direction):
    """Backtrack from the full step until the energy decreases enough (Armijo); None if no
    halving does."""
    if slope >= 0.0:
        return None
    alpha = 1.0
    for _ in range(options.max_halvings):
        trial = v + alpha * step
        if area is None or area.restore(trial, direction):
            trial_energy, gradient, pose = objective.evaluate(trial)
            if trial_energy <= energy + options.armijo * alpha * slope:
                return trial, trial_energy, gradient, pose
        alpha *= 0.5
    return None


def _wolfe_search(objective, options, v, energy, slope, step):
    """A step length meeting the strong Wolfe conditions along ``step`` (Nocedal and Wright,
    algorithms 3.5 and 3.6): sufficient decrease (``options.armijo``) and a slope reduced to
    ``options.wolfe_curvature`` of the first. From the full step it doubles while the energy
    keeps falling steeply, then narrows the bracket by safeguarded cubic interpolation of the
    energies and slopes at its two ends (quadratic where the cubic has no minimum).

    Returns ``(v, energy, half gradient, pose)`` at the step taken, or None when no trial
    lowers the energy (``slope`` must be negative). ``options.max_halvings`` bounds the trials.
    """
    if slope >= 0.0:
        return None
    curvature = options.wolfe_curvature
    low, low_energy, low_slope, best = 0.0, energy, slope, None
    high = high_energy = high_slope = None
    alpha = 1.0
    for _ in range(options.max_halvings):
        trial = v + alpha * step
        trial_energy, gradient, pose = objective.evaluate(trial)
        trial_slope = 2.0 * float(gradient @ step)
        if trial_energy > energy + options.armijo * alpha * slope or (best is not None and trial_energy >= low_energy):
            high, high_energy, high_slope = alpha, trial_energy, trial_slope
        else:
            if abs(trial_slope) <= -curvature * slope:
                return trial, trial_energy, gradient, pose
            # The minimum lies on the side the slope points to: if that is away from high (or
            # past the largest trial so far), the old low becomes the bracket's other end. The
            # bracket may run either way (algorithm 3.6 keeps low the lower energy), so the test
            # is on the slope's sign relative to high - low, not on the sign alone.
            if trial_slope * ((high - low) if high is not None else 1.0) >= 0.0:
                high, high_energy, high_slope = low, low_energy, low_slope
            low, low_energy, low_slope, best = alpha, trial_energy, trial_slope, (trial, trial_energy, gradient, pose)
        if high is None:
            alpha *= 2.0
            continue
        width = high - low
        if abs(width) <= 1e-12 * max(abs(high), 1.0):
            break
        left, right = min(low, high), max(low, high)
        alpha = float(np.clip(_interpolate(low, low_energy, low_slope, high, high_energy, high_slope),
                              left + 0.1 * (right - left), right - 0.1 * (right - left)))
    return best


def _interpolate(a, fa, da, b, fb, db):
    """Minimiser of the cubic through values ``fa, fb`` and slopes ``da, db`` at ``a, b``
    (Nocedal and Wright, equation 3.59); where it has none, of the quadratic through ``fa``,
    ``da`` and ``fb``, or the midpoint."""
    d1 = da + db - 3.0 * (fa - fb) / (a - b)
    radicand = d1 * d1 - da * db
    if radicand >= 0.0:
        d2 = np.copysign(np.sqrt(radicand), b - a)
        denominator = db - da + 2.0 * d2
        if denominator != 0.0:
            return b - (b - a) * (db + d2 - d1) / denominator
    width = b - a
    curve = fb - fa - da * width
    return a - da * width * width / (2.0 * curve) if curve > 0.0 else a + 0.5 * width
