"""Which graph points a solve moves, and the split of every linear map into free and fixed parts.

Handles are hard constraints, a connected part of the graph with no handle stays at rest, and
one held by a single handle point is carried with it, unturned (it could turn about the point at
no cost, so no solve would settle it); all these are *fixed*, the rest are *free*. A solve
iterates on the free points' coordinates stacked ``v = [x; y]`` (length ``2 f``). Every term
that is linear in the positions (the paper's rows ``A``, the fold penalty's triangle edges)
splits the same way: ``M V = M_c c + [M_f 0; 0 M_f] v`` with ``M V`` kept coordinate-major.
:meth:`Unknowns.split` makes that split, once for all of them.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import block_diag

__all__ = ["Unknowns"]


class Unknowns:
    """The free and fixed points of a graph under a set of handles.

    Parameters
    ----------
    graph : solver.Graph
    handles : (h,) int ndarray
        Graph points moved to targets (validated by the caller).

    Attributes
    ----------
    free : (f,) int64 ndarray
        Points the solve moves.
    fixed : (c,) int64 ndarray
        Handles and the points of islands without handles or held by one handle point.
    resting : (n,) bool ndarray
        Points of islands without handles: they stay at rest.
    handles : (h,) int64 ndarray
        The handles, as given.
    islands : (n,) int ndarray
        Each point's island (``graph.components()``).
    held_by : (k,) int64 ndarray
        How many handle points each island has.
    carrier : (n,) int64 ndarray
        For each point of an island held by one handle point, that point (-1 elsewhere, and on
        the handle itself): it moves by its carrier's displacement, rigidly.
    """

    def __init__(self, graph, handles):
        self.handles = handles = np.asarray(handles, dtype=np.int64)
        fixed = np.zeros(graph.n, dtype=bool)
        fixed[handles] = True
        self.islands = labels = graph.components()
        self.held_by = held_by = np.bincount(labels[handles], minlength=labels.max() + 1)
        self.resting = held_by[labels] == 0
        only = np.full(len(held_by), -1, dtype=np.int64)
        single = held_by[labels[handles]] == 1
        only[labels[handles[single]]] = handles[single]
        self.carrier = np.where(fixed, -1, only[labels])
        fixed |= self.resting | (self.carrier >= 0)
        self.free = np.flatnonzero(~fixed)
        self.fixed = np.flatnonzero(fixed)

    def place(self, positions, rest):
        """Put the points that are fixed but not handles where they belong (in place): at rest,
        or carried by their one handle point's displacement, given the handles' places in
        ``positions`` (n, 2)."""
        positions[self.resting] = rest[self.resting]
        carried = np.flatnonzero(self.carrier >= 0)
        positions[carried] = rest[carried] + positions[self.carrier[carried]] - rest[self.carrier[carried]]

    def split(self, matrix):
        """Split a linear map of the positions into its action on ``v`` and on the fixed points.

        Parameters
        ----------
        matrix : (r, n) scipy.sparse matrix

        Returns
        -------
        free_block : (2 r, 2 f) scipy.sparse.csr_matrix
            ``[M_f 0; 0 M_f]``: rows of x then rows of y from ``v``.
        free_block_transpose : (2 f, 2 r) scipy.sparse.csr_matrix
        fixed_columns : (r, c) scipy.sparse.csr_matrix
            ``M_c``, applied to the fixed points' ``(c, 2)`` positions.
        """
        matrix = matrix.tocsc()
        free_columns = matrix[:, self.free]
        free_block = block_diag([free_columns, free_columns], format="csr")
        return free_block, free_block.T.tocsr(), matrix[:, self.fixed].tocsr()
