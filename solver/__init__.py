"""2D shape deformation by nonlinear least squares (Weng, Xu, Wu, Zhou and Guo, 2006).

A Blender-free library: numpy and scipy in, numpy out.

>>> import numpy as np, solver
>>> square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
>>> graph = solver.build_graph([square])
>>> left = np.flatnonzero(graph.points[:, 0] < 1e-9)
>>> deformer = solver.Deformer(graph, left)
>>> pose = deformer.solve(graph.points[left] + [0.0, 0.1]).positions

Public names: :func:`build_graph`, :class:`Graph`, :class:`Deformer`, :func:`trace_silhouette`,
:func:`bind` and :class:`Binding`.

The Blender add-on's own helpers (planes, handles, dragging, outlines of meshes and curves,
stroke silhouettes, picture cut-outs) live in the subpackage :mod:`solver.rigging`, which this
package never imports.
"""

from .binding import Binding, bind
from .deformer import Deformer, Solution
from .graph import Graph, build_graph
from .trace import trace_silhouette

__all__ = ["Graph", "build_graph", "Deformer", "Solution", "trace_silhouette", "bind", "Binding"]
