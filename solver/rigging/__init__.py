"""Blender-free helpers for rigging a shape in Blender, kept apart from the paper's library.

What the add-on needs around the solver, as plain numpy: fitting the plane a 3D shape lies in
(:mod:`.plane`), handle frames and the regions they carry (:mod:`.handles`), the ray geometry of
dragging in the viewport (:mod:`.drag`), outlines of meshes and Bezier curves (:mod:`.outline`),
the areas stroke drawings and pictures cover (:mod:`.silhouette`), and the heights that
layer a shape folded over itself (:mod:`.depth`).

These modules may use :mod:`solver`; :mod:`solver` never imports them.
"""

from . import depth, drag, handles, outline, plane, silhouette
from .plane import Plane, fit_plane

__all__ = ["depth", "drag", "handles", "outline", "plane", "silhouette", "Plane", "fit_plane"]
