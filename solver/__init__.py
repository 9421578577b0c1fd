"""2D shape deformation by nonlinear least squares (Weng, Xu, Wu, Zhou and Guo, 2006).

A Blender-free library: numpy and scipy in, numpy out.

>>> import numpy as np, solver
>>> square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
>>> graph = solver.build_graph([square])
>>> left = np.flatnonzero(graph.points[:, 0] < 1e-9)
>>> deformer = solver.Deformer(graph, left)
>>> pose = deformer.solve(graph.points[left] + [0.0, 0.1]).positions

Public names: :func:`build_graph`, :class:`Graph`, :class:`Deformer`, :class:`Solution`,
:class:`Options` (every knob of a solve), :class:`CoarseCopies` (coarse levels a caller keeps
between deformers of one graph), :class:`UncoveredPoints` (the weights leave points undecided), :func:`trace_silhouette`, :func:`bind` and :class:`Binding`.

Layout: what is minimised is in :mod:`~solver.energy` (the paper's terms), :mod:`~solver.folds`
(the fold penalty), :mod:`~solver.area` (the area constraint) and :mod:`~solver.unknowns` (free
and fixed points); how, in :mod:`~solver.optimizer`, over a preconditioner of
:mod:`~solver.preconditioner`; from a start of :mod:`~solver.start`; :mod:`~solver.deformer`
puts them together.

The Blender add-on's own helpers (planes, handles, dragging, outlines of meshes and curves,
stroke silhouettes, picture cut-outs) live in the subpackage :mod:`solver.rigging`, which this
package never imports.
"""

from .binding import Binding, bind
from .deformer import Deformer, Solution
from .energy import UncoveredPoints
from .graph import Graph, build_graph
from .options import Options
from .start import CoarseCopies
from .trace import trace_silhouette

__all__ = ["Graph", "build_graph", "Deformer", "Solution", "Options", "CoarseCopies", "trace_silhouette",
           "bind", "Binding", "UncoveredPoints"]
