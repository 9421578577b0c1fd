"""Where a solve starts: a pose that depends on the handles' targets alone.

- :class:`SimilarityStart`: the as-similar-as-possible pose (one linear solve, factorised once
  per handle set) that turns free limbs with what they hang from.
- :class:`CoarseStart`: the converged pose of a coarse copy of the shape, carried to the fine
  points by its binding, so a dense graph poses like a sparse one.

Coarse copies depend on the graph alone while a deformer is rebuilt for every change of handles
or weights, so they are kept in a :class:`CoarseCopies` that the caller owns and may pass from
one deformer to the next (the add-on's rig cache does).
"""

from __future__ import annotations

import hashlib

import numpy as np
import qdldl
from scipy.sparse import identity, triu
from scipy.spatial import cKDTree

from .binding import bind
from .energy import similarity_rows
from .graph import build_graph
from .outline import outline_graph
from .shapes import box_centre

__all__ = ["CoarseCopies", "CoarseStart", "SimilarityStart"]


class SimilarityStart:
    """The as-similar-as-possible pose for given fixed points (see
    :func:`solver.energy.similarity_rows`).

    Parameters
    ----------
    graph : solver.Graph
    unknowns : solver.unknowns.Unknowns
    """

    def __init__(self, graph, unknowns):
        n = graph.n
        free = unknowns.free
        self._free = free
        similarity = similarity_rows(graph.points, graph.triangles).tocsc()
        stacked_free = np.concatenate([free, n + free])
        self._stacked_fixed = np.concatenate([unknowns.fixed, n + unknowns.fixed])
        similarity_free = similarity[:, stacked_free]
        self._similarity_fixed = similarity[:, self._stacked_fixed].tocsr()
        self._similarity_free_transpose = similarity_free.T.tocsr()
        normal = (self._similarity_free_transpose @ similarity_free).tocsc()
        # Free points touching no triangle would make this singular; a tiny pull towards their
        # rest positions keeps them there and changes nothing else measurably.
        diagonal = normal.diagonal()
        tiny = 1e-12 * (float(diagonal.max()) if len(diagonal) else 1.0)
        normal = normal + tiny * identity(normal.shape[0], format="csc")
        # The pull settles what the handles leave open (islands held by one point are fixed,
        # carried by it: solver.unknowns): towards the rest moved as the island's handles move
        # on average, which the similarity energy has at its minimum too. Solved about the rest
        # shape's centre: far from the origin the pull's rounding turned a shape 1e6 times
        # smaller than its offset by more than its size.
        self._origin = box_centre(graph.points)
        self._tiny = tiny
        self._rest = graph.points
        self._rest_free = graph.points[free] - self._origin
        island = unknowns.islands
        self._handles = unknowns.handles
        self._handle_island, self._free_island = island[self._handles], island[free]
        self._islands = int(island.max()) + 1 if n else 0
        self._factor = qdldl.Solver(triu(normal, format="csc"), upper=True)

    def _pull(self, positions, rest):
        """The tiny pull's right-hand side: towards the rest shifted by each island's mean
        handle displacement (islands without handles are not free)."""
        moved = positions[self._handles] - rest[self._handles]
        count = np.maximum(np.bincount(self._handle_island, minlength=self._islands), 1)
        shift = np.stack([np.bincount(self._handle_island, moved[:, axis], self._islands) / count
                          for axis in range(2)], axis=1)
        return self._tiny * (self._rest_free + shift[self._free_island]).T.ravel()

    def pose(self, positions, targets=None):
        """``positions`` (n, 2) with the free points moved to the as-similar-as-possible pose
        for the fixed ones (a new array); ``targets`` is not needed (the fixed points hold them)."""
        origin = self._origin
        stacked = np.concatenate([positions[:, 0] - origin[0], positions[:, 1] - origin[1]])
        rhs = self._pull(positions, self._rest) - self._similarity_free_transpose @ (
            self._similarity_fixed @ stacked[self._stacked_fixed])
        free = self._factor.solve(rhs)
        k = len(self._free)
        positions = positions.copy()
        positions[self._free, 0] = free[:k] + origin[0]
        positions[self._free, 1] = free[k:] + origin[1]
        return positions


class CoarseCopies:
    """Coarse copies of shapes, kept for reuse between deformers of the same graph.

    Keyed by the graph's points and loops, so a copy is never used for another shape; the
    ``kept`` most recently used are kept (an attribute: a caller that knows how many shapes it
    deforms at once may raise it).
    """

    def __init__(self, kept=8):
        self.kept = int(kept)
        self._copies = {}

    def get(self, graph, interior=None, detail=None):
        """A coarse copy of ``graph``'s shape and the binding of ``graph``'s points to it.

        Parameters
        ----------
        graph : solver.Graph
        interior : int, optional
            About this many interior points (:func:`~solver.outline.outline_graph`, outline kept
            to ``detail`` times its spacing); None if the outline will not make one. Without it,
            the default spacing (:func:`~solver.graph.build_graph`).
        detail : float, optional

        Returns
        -------
        (solver.Graph, solver.Binding) or None
        """
        loops = graph.boundary_loops
        digest = hashlib.blake2b(graph.points.tobytes(), digest_size=16)
        digest.update(np.array([len(loop) for loop in loops], dtype=np.int64).tobytes())
        digest.update(np.concatenate(loops).astype(np.int64).tobytes())
        key = (digest.digest(), interior, detail)
        if key in self._copies:
            self._copies[key] = self._copies.pop(key)  # the most recently used goes last
        else:
            rings = [graph.points[loop] for loop in loops]
            if interior is None:
                coarse = build_graph(rings)
            else:
                try:
                    coarse = outline_graph(rings, interior, detail)
                except ValueError:  # an outline the coarse copy cannot be built from
                    coarse = None
            while self._copies and len(self._copies) >= self.kept:
                del self._copies[next(iter(self._copies))]
            self._copies[key] = None if coarse is None else (coarse, bind(coarse, graph.points))
        return self._copies[key]


class CoarseStart:
    """The pose of a coarse copy of the shape, carried to a large graph's points.

    A graph of a few hundred points built from the same boundary solves with Newton steps in
    milliseconds and gets the turns of whole limbs right; the fine iterations then fix local
    detail. Starting there also keeps a dense graph's pose close to the coarse one's: from the
    as-similar-as-possible start, a 9,000-point horse turning its head settled in a minimum
    with 9% more energy, 3% of its size away from the coarse pose.

    Parameters
    ----------
    graph : solver.Graph
    handles : (h,) int ndarray
    copy : (solver.Graph, solver.Binding)
        The coarse copy and the binding of ``graph``'s points to it (:meth:`CoarseCopies.get`).
    make_deformer : callable
        ``make_deformer(coarse_graph, coarse_handles)``: the deformer that solves the copy.
    """

    def __init__(self, graph, handles, copy, make_deformer):
        self.copy = copy
        coarse, self.binding = copy
        rest = graph.points[handles]
        # Each coarse point nearest a handle point follows that handle point's target.
        _, nearest = cKDTree(coarse.points).query(rest)
        coarse_handles, self._first = np.unique(nearest, return_index=True)
        self._offset = coarse.points[coarse_handles] - rest[self._first]
        self.deformer = make_deformer(coarse, coarse_handles)

    def pose(self, positions, targets):
        """Fine graph positions (n, 2) for the handles' ``targets`` (h, 2); ``positions`` is
        not needed (the coarse copy's pose is carried to every fine point)."""
        coarse = self.deformer.solve(targets[self._first] + self._offset)
        return self.binding.apply(coarse.positions)
