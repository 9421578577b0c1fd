"""The methods compared in benchmarks/compare.py, each behind the same small interface.

Every method is made from a graph (points + the same triangles), the handle groups of a drag
(see ``benchmarks.shapes.DRAGS``) and returns a :class:`Method` with

* ``bind_seconds``: everything that depends on the handle set only (factorisations, binding);
* ``solve()``: positions for the drag's targets, ``(n, 2)``; called repeatedly for timing;
* ``iterations``: iterations the last ``solve()`` ran (``None`` when it has no such notion).

bpy is imported only inside :func:`blender_laplacian`, so the rest of this module (and the
tests) never load Blender.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np
from scipy.sparse.linalg import splu

import solver
from benchmarks.shapes import drag_targets

__all__ = ["Method", "ours", "linear_baseline", "plain_iteration", "libigl_arap", "blender_laplacian",
           "fine_factor"]


def fine_factor(deformer):
    """The factor one of ``deformer``'s iterations back-substitutes with, over the whole graph:
    the two-grid preconditioner's fine (paper's) factor (of the Krylov-Newton solve's two-grid
    on large graphs), or with ``newton=True`` (and on graphs too small for a coarse copy) the
    Newton factor."""
    matrix = getattr(deformer._preconditioner, "_two_grid", deformer._preconditioner)
    return getattr(matrix, "_smoother", matrix)


@dataclass
class Method:
    name: str
    bind_seconds: float
    solve: Callable[[], np.ndarray]
    iterations: Optional[int] = None
    extra: dict = field(default_factory=dict)


def ours(graph, groups, preserve_area=False, weights=None, name=None, prevent_flips=False):
    """This solver, default iterations and tolerance."""
    handles, targets = drag_targets(graph, groups)
    start = time.perf_counter()
    deformer = solver.Deformer(graph, handles, weights=weights, preserve_area=preserve_area,
                               prevent_flips=prevent_flips)
    bind = time.perf_counter() - start
    method = Method(name or ("ours + area" if preserve_area else "ours"), bind, None)

    def solve():
        solution = deformer.solve(targets)
        method.iterations = solution.iterations
        method.extra["solution"] = solution
        return solution.positions

    method.solve = solve
    method.extra["deformer"] = deformer
    return method


class _Linear:
    """Pieces of the paper's linear algebra built from the deformer's public internals.

    ``A`` is ``deformer.energy.matrix``; with free/fixed columns ``A_f``, ``A_c`` the paper's step
    (9) on the free points is ``V_f = (A_f^T A_f)^-1 A_f^T (b - A_c V_c)``: one back-substitution
    with a factor made once.
    """

    def __init__(self, deformer):
        self.deformer = deformer
        matrix = deformer.energy.matrix.tocsc()
        self.free = deformer.free
        self.fixed = np.setdiff1d(np.arange(deformer.graph.n), self.free)
        self.a_free = matrix[:, self.free]
        self.a_fixed = matrix[:, self.fixed]
        self.a_free_transpose = self.a_free.T.tocsr()
        self.factor = splu((self.a_free_transpose @ self.a_free).tocsc())

    def step(self, positions, b):
        rhs = self.a_free_transpose @ (b - self.a_fixed @ positions[self.fixed])
        out = positions.copy()
        out[self.free] = self.factor.solve(np.ascontiguousarray(rhs))
        return out


def _posed_rest(graph, handles, targets):
    """Rest positions with the handles moved onto their targets."""
    positions = graph.points.copy()
    positions[handles] = targets
    return positions


def linear_baseline(graph, groups):
    """The linear method the paper argues against: the same ``A``, ``b`` frozen at rest.

    ``b(V_rest) = A V_rest``: every curve Laplacian, mean value row and inner edge keeps its rest
    vector, unrotated. One solve.
    """
    handles, targets = drag_targets(graph, groups)
    start = time.perf_counter()
    deformer = solver.Deformer(graph, handles)
    linear = _Linear(deformer)
    rest_targets = deformer.energy.targets(deformer.energy.matrix @ graph.points)
    bind = time.perf_counter() - start
    posed = _posed_rest(graph, handles, targets)
    return Method("linear (rest rotations)", bind, lambda: linear.step(posed, rest_targets), 1)


def plain_iteration(deformer, targets, iterations, initial=None):
    """The paper's iteration (9) from ``initial`` (default: rest with handles on targets).

    Returns
    -------
    positions : (n, 2) ndarray
    energies : list of float
        The energy ``||A V - b(V)||^2`` before the first iteration and after each one.
    """
    linear = _Linear(deformer)
    energy = deformer.energy
    positions = _posed_rest(deformer.graph, deformer.handles, targets) if initial is None else initial.copy()
    positions[deformer.handles] = targets
    energies = [energy.evaluate(positions)[0]]
    for _ in range(iterations):
        positions = linear.step(positions, energy.targets(energy.matrix @ positions))
        energies.append(energy.evaluate(positions)[0])
    return positions, energies


def libigl_arap(graph, groups, iterations=10, converge_tolerance=1e-4, most=2000):
    """libigl's 2D ARAP (``igl.arap_precomputation`` / ``igl.arap_solve``), started at rest.

    ``iterations=None`` runs to convergence: first one iteration at a time until no vertex moves
    more than ``converge_tolerance * graph.size`` (ours uses the same stopping rule) or ``most``
    iterations, then the timed ``solve()`` runs that many iterations in one call.
    """
    import igl

    handles, targets = drag_targets(graph, groups)
    vertices = np.ascontiguousarray(graph.points)
    faces = np.ascontiguousarray(graph.triangles, dtype=np.int64)
    b = np.ascontiguousarray(handles, dtype=np.int32)
    bc = np.ascontiguousarray(targets)
    data = igl.ARAPData()
    data.max_iter = 1 if iterations is None else int(iterations)
    start = time.perf_counter()
    igl.arap_precomputation(vertices, faces, 2, b, data)
    bind = time.perf_counter() - start
    count = iterations
    if iterations is None:
        positions = vertices
        for count in range(1, most + 1):
            moved = igl.arap_solve(bc, data, positions)
            step = np.abs(moved - positions).max()
            positions = moved
            if step <= converge_tolerance * graph.size:
                break
        data.max_iter = count
    name = "libigl ARAP, converged" if iterations is None else f"libigl ARAP, {iterations} it"
    return Method(name, bind, lambda: np.asarray(igl.arap_solve(bc, data, vertices)), count)


def blender_laplacian(graph, groups, iterations=1):
    """Blender's Laplacian Deform modifier under PyPI bpy, on a mesh of the same triangles.

    Anchors: a vertex group of every handle. Each moved group gets a vertex group, an empty and
    a Hook modifier (before the Laplacian Deform) that applies the group's motion; pinned groups
    need no hook. The bind runs at rest; ``solve()`` moves the empties to the drag, updates the
    depsgraph and reads the evaluated mesh.
    """
    import bpy
    from mathutils import Matrix

    handles, targets = drag_targets(graph, groups)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    mesh = bpy.data.meshes.new("shape")
    n = graph.n
    vertices = np.zeros((n, 3), dtype=np.float32)
    vertices[:, :2] = graph.points
    mesh.vertices.add(n)
    mesh.vertices.foreach_set("co", vertices.ravel())
    t = len(graph.triangles)
    mesh.loops.add(3 * t)
    mesh.loops.foreach_set("vertex_index", graph.triangles.astype(np.int32).ravel())
    mesh.polygons.add(t)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * t, 3, dtype=np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(t, 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    mesh.validate()
    ob = bpy.data.objects.new("shape", mesh)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob

    anchors = ob.vertex_groups.new(name="anchors")
    anchors.add([int(i) for i in handles], 1.0, "REPLACE")
    hooks = []
    for k, (indices, (m, shift)) in enumerate(groups):
        if np.allclose(m, np.eye(2)) and not np.any(shift):
            continue
        group = ob.vertex_groups.new(name=f"hook{k}")
        group.add([int(i) for i in indices], 1.0, "REPLACE")
        empty = bpy.data.objects.new(f"hook{k}", None)
        bpy.context.scene.collection.objects.link(empty)
        hook = ob.modifiers.new(f"hook{k}", "HOOK")
        hook.object = empty
        hook.vertex_group = group.name
        hook.falloff_type = "NONE"
        hook.matrix_inverse = Matrix.Identity(4)
        pose = Matrix.Identity(4)
        for i in range(2):
            for j in range(2):
                pose[i][j] = m[i, j]
            pose[i][3] = shift[i]
        hooks.append((empty, pose))
    modifier = ob.modifiers.new("laplacian", "LAPLACIANDEFORM")
    modifier.vertex_group = anchors.name
    modifier.iterations = iterations

    depsgraph = bpy.context.evaluated_depsgraph_get()
    start = time.perf_counter()
    with bpy.context.temp_override(object=ob, active_object=ob):
        bpy.ops.object.laplaciandeform_bind(modifier=modifier.name)
    depsgraph.update()  # the bind itself happens during this evaluation
    bind = time.perf_counter() - start
    if not modifier.is_bind:
        raise RuntimeError("Laplacian Deform did not bind")

    buffer = np.empty(3 * n, dtype=np.float32)
    nudge = Matrix.Translation((1e-6 * graph.size, 0.0, 0.0))
    state = {"flip": False}

    def solve():
        # Alternate between the pose and a pose nudged by 1e-6 of the size so every call
        # really re-evaluates; the returned result is always for the exact pose.
        state["flip"] = not state["flip"]
        for empty, pose in hooks:
            empty.matrix_world = (nudge @ pose) if state["flip"] else pose
        depsgraph.update()
        evaluated = ob.evaluated_get(depsgraph).data
        evaluated.attributes["position"].data.foreach_get("vector", buffer)
        return buffer.reshape(n, 3)[:, :2].astype(np.float64)

    def exact():
        state["flip"] = True
        return solve()

    method = Method(f"Blender Laplacian Deform, {iterations} it", bind, solve, iterations)
    method.extra["exact"] = exact
    method.extra["z"] = lambda: float(np.abs(buffer.reshape(n, 3)[:, 2]).max())
    return method
