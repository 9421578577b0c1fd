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


def star(points=5, inner=0.42):
    """A regular star: ``points`` tips on the unit circle, notches at radius ``inner``."""
    angle = np.pi / 2 + np.arange(2 * points) * np.pi / points
    radius = np.where(np.arange(2 * points) % 2 == 0, 1.0, inner)
    return [np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)]


def stick_figure(width=0.07):
    """A round head on limbs so thin (``width`` ~ 0.04 of the size) that they get no lattice
    point inside: only boundary points carry the arms and legs."""
    lines = [[(0, 1.4), (0, 0.5)],
             [(-0.75, 0.9), (-0.35, 1.15), (0, 1.2), (0.35, 1.15), (0.8, 1.4)],
             [(-0.45, -0.45), (-0.2, 0.05), (0, 0.5), (0.25, 0.05), (0.4, -0.45)]]
    parts = [shapely.Point(0, 1.65).buffer(0.28)] + [shapely.LineString(line).buffer(width) for line in lines]
    return _rings(shapely.union_all(parts))


def _tapered(path, width):
    """A band of half-width ``width[i]`` about ``path[i]``, (k, 2) and (k,)."""
    tangent = np.gradient(path, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1)[:, None]
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1) * width[:, None]
    return shapely.Polygon(np.concatenate([path + normal, (path - normal)[::-1]])).buffer(0)


def octopus(arms=6):
    """An oval body with ``arms`` long wavy arms tapering to thin tips."""
    body = shapely.affinity.scale(shapely.Point(0, 0.55).buffer(0.6), 1.0, 1.25)
    t = np.linspace(0, 1, 40)[:, None]
    limbs = []
    for k in range(arms):
        angle = np.radians(-160 + 140 * k / (arms - 1))
        out = np.array([np.cos(angle), np.sin(angle)])
        side = np.array([-out[1], out[0]])
        path = (0.3 + 1.7 * t) * out + 0.25 * np.sin(2.5 * np.pi * t + k) * t * side
        limbs.append(_tapered(path, 0.11 - 0.07 * t[:, 0]))
    return _rings(shapely.union_all([body] + limbs))


def islands():
    """Three separate pieces: a ring (one hole), a bar and a triangle."""
    ring = shapely.Point(0, 0).buffer(1.0).difference(shapely.Point(0, 0).buffer(0.5))
    bar = shapely.box(1.5, -0.9, 3.8, -0.3)
    triangle = shapely.Polygon([(1.8, 0.2), (3.6, 0.4), (2.5, 1.6)])
    return _rings(shapely.union_all([ring, bar, triangle]))


def drawn_cat(size=240):
    """A cat painted into a bitmap (scikit-image's drawing) and traced: eye holes, four legs,
    pointed ears and a thin curled tail, with the staircase outline of a traced image."""
    from skimage import draw

    image = np.zeros((size, size), dtype=bool)

    def paint(rows, columns, value=True):
        image[rows, columns] = value

    paint(*draw.ellipse(90, 130, 50, 80, image.shape))
    paint(*draw.disk((160, 70), 38, shape=image.shape))
    paint(*draw.polygon([180, 228, 196], [38, 45, 72], image.shape))
    paint(*draw.polygon([196, 228, 180], [68, 95, 102], image.shape))
    t = np.linspace(0, 1, 80)
    for row, column in zip(80 + 120 * t ** 1.5, 200 + 22 * np.sin(3 * t)):
        paint(*draw.disk((row, column), 7, shape=image.shape))
    for column in (75, 110, 150, 185):
        paint(*draw.rectangle((5, column - 9), (60, column + 9), shape=image.shape))
    for column in (56, 84):
        paint(*draw.disk((168, column), 6, shape=image.shape), False)
    return solver.trace_silhouette(image, tolerance=1.0)


def traced_blob(size=200):
    """An organic outline with two holes: a sum of Gaussian bumps and dents, thresholded and
    traced."""
    y, x = np.mgrid[0:size, 0:size] / size
    field = np.zeros_like(x)
    bumps = [(0.35, 0.45, 0.16, 1.0), (0.62, 0.55, 0.13, 1.0), (0.75, 0.3, 0.08, 1.0),
             (0.3, 0.75, 0.07, 0.9), (0.2, 0.25, 0.06, 0.9), (0.38, 0.47, 0.045, -1.2),
             (0.63, 0.56, 0.035, -1.0)]
    for cx, cy, spread, weight in bumps:
        field += weight * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * spread ** 2))
    return solver.trace_silhouette(field > 0.55, tolerance=1.0)


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
