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


# ---------------------------------------------------------------------------------------------
# Drags for the peer comparison (benchmarks/compare.py). A drag is a list of handle groups, each
# a set of graph points and the 2D affine motion (M, t) taking their rest positions to targets:
# ``target = rest @ M.T + t``. Groups are chosen in bounding-box fractions (u, v in [0, 1]), so
# the same drag applies to a shape at any resolution.

def _unit(graph):
    low = graph.points.min(axis=0)
    extent = np.ptp(graph.points, axis=0)
    return (graph.points - low) / extent, low, extent


def _disk(graph, u, v, radius):
    """Points within ``radius`` (a fraction of the shape's size) of bounding-box point (u, v)."""
    _, low, extent = _unit(graph)
    centre = low + np.array([u, v]) * extent
    return np.flatnonzero(np.linalg.norm(graph.points - centre, axis=1) < radius * graph.size)


def _strip(graph, below=None, above=None):
    unit, _, _ = _unit(graph)
    mask = np.ones(graph.n, dtype=bool)
    if below is not None:
        mask &= unit[:, 1] <= below
    if above is not None:
        mask &= unit[:, 1] >= above
    return np.flatnonzero(mask)


def _shift(graph, du, dv):
    _, _, extent = _unit(graph)
    return np.eye(2), np.array([du, dv]) * extent


def _turn(graph, u, v, degrees):
    _, low, extent = _unit(graph)
    pivot = low + np.array([u, v]) * extent
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    rotation = np.array([[c, -s], [s, c]])
    return rotation, pivot - rotation @ pivot


_PIN = (np.eye(2), np.zeros(2))


def _drags_horse(g):
    hooves = _strip(g, below=0.06)
    head = _disk(g, 0.93, 0.78, 0.06)
    tail = _disk(g, 0.06, 0.55, 0.05)
    front = np.intersect1d(hooves, np.flatnonzero(g.points[:, 0] > g.points[:, 0].mean()))
    hind = np.setdiff1d(hooves, front)
    body = _disk(g, 0.45, 0.62, 0.06)
    return {
        "bend": [(hooves, _PIN), (head, _shift(g, -0.3, 0.25))],
        "stretch": [(np.union1d(hind, tail), _PIN), (np.union1d(front, head), _shift(g, 0.3, 0.0))],
        "rotate": [(np.union1d(hooves, body), _PIN), (head, _turn(g, 0.75, 0.62, -90.0))],
    }


def _drags_glyph(g):
    bottom = _strip(g, below=0.04)
    top = _strip(g, above=0.96)
    return {
        "bend": [(bottom, _PIN), (top, _shift(g, 0.45, -0.1))],
        "stretch": [(bottom, _PIN), (top, _shift(g, 0.0, 0.4))],
        "rotate": [(bottom, _PIN), (top, _turn(g, 0.05, 0.55, 90.0))],
    }


DRAGS = {"horse": _drags_horse, "glyph B": _drags_glyph}
"""Shape name -> function(graph) -> {drag name: [(point indices, (M, t)), ...]}."""


def drag_targets(graph, groups):
    """Handles and targets of a drag (groups as in ``DRAGS``), in group order.

    Returns
    -------
    handles : (h,) int ndarray
    targets : (h, 2) float ndarray
    """
    handles = np.concatenate([indices for indices, _ in groups])
    if len(np.unique(handles)) != len(handles):
        raise ValueError("handle groups overlap")
    targets = np.concatenate([graph.points[indices] @ m.T + t for indices, (m, t) in groups])
    return handles, targets
