"""Shapes for the solver tests: real silhouettes and glyphs, not only circles."""

import numpy as np


def disk(radius=1.0, count=64, centre=(0.0, 0.0)):
    angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    return np.stack([centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle)], axis=1)


def glyph_rings(text, size=10.0):
    """Outline rings of ``text`` in DejaVu Sans (shipped inside matplotlib)."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    path = TextPath((0, 0), text, size=size, prop=FontProperties(family="DejaVu Sans"))
    return [np.asarray(polygon[:-1], dtype=float) for polygon in path.to_polygons(closed_only=True)]


def figure_rings():
    """A gingerbread figure (head, body, arms, legs, two eye holes) made by shapely unions, which
    leave vertices a hair apart where the parts meet; its boundary is much denser than its
    interior lattice."""
    import shapely
    from shapely import affinity

    head = shapely.Point(0, 3.1).buffer(0.7)
    body = affinity.scale(shapely.Point(0, 1.4).buffer(1.0), 0.8, 1.15)
    limbs = [shapely.LineString(line).buffer(0.28) for line in (
        [(-0.5, 2.1), (-1.6, 1.6), (-2.2, 0.9)], [(0.5, 2.1), (1.6, 1.6), (2.2, 0.9)],
        [(-0.35, 0.6), (-0.6, -0.6), (-0.7, -1.6)], [(0.35, 0.6), (0.6, -0.6), (0.7, -1.6)])]
    eyes = shapely.union_all([shapely.Point(x, 3.25).buffer(0.12) for x in (-0.25, 0.25)])
    shape = shapely.union_all([head, body] + limbs).difference(eyes)
    return [np.asarray(ring.coords)[:-1] for ring in [shape.exterior, *shape.interiors]]


def region(points, centre, radius):
    return np.flatnonzero(np.linalg.norm(points - np.asarray(centre), axis=1) < radius)


def hooves_and_head(points):
    """On a graph of the traced horse (any density): hooves pinned, head dragged up and back by
    a third of the horse's size. Returns handles, targets and how many handles are the head."""
    hooves = [region(points, c, 12.0) for c in [(60, 20), (125, 28), (262, 22), (285, 18)]]
    head = region(points, (370, 240), 20.0)
    handles = np.concatenate(hooves + [head])
    targets = points[handles].copy()
    targets[-len(head):] += [-120.0, 80.0]
    return handles, targets, len(head)
