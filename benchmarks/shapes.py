"""Test shapes for benchmarks and the demo: generated here or shipped inside dev wheels.

Each shape comes with handles: regions of graph points that are pinned or dragged, so every
method in a comparison gets exactly the same input.
"""

from __future__ import annotations

import numpy as np
import shapely

import solver


def flower():
    """A five-petal flower on a curved stem with a leaf (the paper's Figure 7 kind of shape)."""
    angle = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    radius = 1.0 + 0.35 * np.cos(5 * angle)
    head = shapely.Polygon(np.stack([radius * np.cos(angle), 3.2 + radius * np.sin(angle)], axis=1))
    t = np.linspace(0, 1, 40)
    spine = np.stack([0.25 * np.sin(np.pi * t), 3.0 * t - 0.6], axis=1)
    stem = shapely.LineString(spine).buffer(0.12)
    leaf = shapely.affinity.rotate(shapely.Point(0.55, 0.9).buffer(1.0).intersection(
        shapely.Point(0.55, 1.9).buffer(1.0)), -50, origin=(0.3, 1.0))
    return _rings(shapely.union_all([head, stem, leaf]))


def character():
    """A gingerbread-style figure: head, body, arms and legs (the paper's Figure 1 kind)."""
    head = shapely.Point(0, 3.1).buffer(0.7)
    body = shapely.affinity.scale(shapely.Point(0, 1.4).buffer(1.0), 0.8, 1.15)
    limbs = [shapely.LineString(line).buffer(0.28) for line in (
        [(-0.5, 2.1), (-1.6, 1.6), (-2.2, 0.9)], [(0.5, 2.1), (1.6, 1.6), (2.2, 0.9)],
        [(-0.35, 0.6), (-0.6, -0.6), (-0.7, -1.6)], [(0.35, 0.6), (0.6, -0.6), (0.7, -1.6)])]
    eye = [shapely.Point(x, 3.25).buffer(0.12) for x in (-0.25, 0.25)]
    return _rings(shapely.union_all([head, body] + limbs).difference(shapely.union_all(eye)))


def horse():
    """scikit-image's horse silhouette, traced (scikit-image is a dev-only dependency)."""
    from skimage.data import horse as horse_image

    return solver.trace_silhouette(horse_image()[::-1] == 0, tolerance=1.0)


def glyph(text="B", size=10.0):
    """Outline of ``text`` in DejaVu Sans (shipped inside matplotlib, dev-only)."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    path = TextPath((0, 0), text, size=size, prop=FontProperties(family="DejaVu Sans"))
    return [np.asarray(p[:-1], dtype=float) for p in path.to_polygons(closed_only=True)]


def _rings(geometry):
    return [ring for island in solver.shapes.geometry_rings(geometry) for ring in island]


def standard_drag(graph, move=(-0.25, 0.2), radius=0.06):
    """Pin the region around the lowest point, drag the region around the highest point.

    Returns
    -------
    handles : (h,) int ndarray
    targets : (h, 2) float ndarray
    """
    points, size = graph.points, graph.size
    low = points[np.argmin(points[:, 1])]
    high = points[np.argmax(points[:, 1])]
    pinned = np.flatnonzero(np.linalg.norm(points - low, axis=1) < radius * size)
    dragged = np.flatnonzero(np.linalg.norm(points - high, axis=1) < radius * size)
    handles = np.concatenate([pinned, dragged])
    targets = points[handles].copy()
    targets[len(pinned):] += np.asarray(move) * size
    return handles, targets


SHAPES = {"flower": flower, "horse": horse, "character": character, "glyph B": glyph}
