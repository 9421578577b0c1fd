# SPDX-License-Identifier: GPL-3.0-or-later
"""What a source module's ``prepare`` returns (see the package's docstring)."""

from dataclasses import dataclass, field
from typing import Callable

__all__ = ["Prepared"]


@dataclass
class Prepared:
    """What binding an object needs, computed before anything is changed.

    Attributes
    ----------
    plane : solver.rigging.Plane
    graph : solver.Graph
    commit : callable(obj)
        Makes the changes binding needs beyond the rig's own (an image plane's cut-out).
    advice : str
        What the user should know about the bound result (empty when nothing).
    modifier_inputs : dict
        Values the deformer modifier's inputs start with, by input name, where this object's
        differ from the node group's defaults (grease pencil: Stroke Order).
    islands : (n,) int32 ndarray or None
        Each graph point's island number, for the cage, where ``commit`` gives the object's points
        theirs (a mesh that is its own graph, in several islands); None elsewhere.
    """

    plane: object
    graph: object
    commit: Callable = field(default=lambda obj: None)
    advice: str = ""
    modifier_inputs: dict = field(default_factory=dict)
    islands: object = None
