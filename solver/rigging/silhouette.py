"""Silhouettes of drawings and pictures: the area a stroke drawing or an image covers.

A stroke drawing (grease pencil, a curve's open splines) covers the union of its strokes, each
swept by its radius, and of the areas its closed, filled strokes (or a curve's closed splines)
enclose. A picture covers its opaque pixels; its cut-out is that silhouette grown by a margin so
no visible pixel is lost, then clipped to the picture.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy import ndimage

from ..shapes import polygonal_part, geometry_rings, shape_geometry
from ..trace import coverage, trace_silhouette

__all__ = ["stroke_silhouette", "image_cutout", "shown_frame", "specks", "map_by_triangles"]


def stroke_silhouette(points, offsets, radii, cyclic=None, min_radius=0.0, tolerance=None, areas=()):
    """The area covered by strokes drawn with a round pen, and by ``areas``.

    Parameters
    ----------
    points : (p, 2) array_like
        All stroke points, stroke after stroke.
    offsets : (s + 1,) array_like of int
        Stroke ``i`` is ``points[offsets[i]:offsets[i + 1]]``.
    radii : (p,) array_like
        Pen radius at each point; a stroke is swept by the mean radius of its points.
    cyclic : (s,) array_like of bool, optional
        Closed strokes: the area they enclose is covered too (a fill). So is what an open
        stroke encloses by itself (its ends drawn over each other, or a loop).
    min_radius : float
        Radius used where a stroke's radius is smaller, so hairlines still make an area.
    tolerance : float, optional
        Simplify the outline by this distance (default: a twentieth of the smallest radius used,
        which loses well under 1% of the area of round ends).
    areas : sequence of (k, 2) array_like, optional
        Rings of areas covered as they are (a curve's closed splines), nested by containment (a
        ring inside another is a hole: see :func:`solver.shapes.shape_geometry`). Strokes are
        swept only where they lie outside them, so a line drawn inside an area (a detail on a
        filled shape) leaves its outline as it is.

    Returns
    -------
    list of (k, 2) float64 ndarray
        Outer rings counter-clockwise, holes clockwise.

    Raises
    ------
    ValueError
        No strokes, non-finite input, strokes that cover no area, or a malformed area ring.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    offsets = np.asarray(offsets, dtype=np.int64).ravel()
    radii = np.asarray(radii, dtype=np.float64).ravel()
    if len(offsets) < 2 or len(points) == 0:
        raise ValueError("there are no strokes")
    if not (np.all(np.isfinite(points)) and np.all(np.isfinite(radii))):
        raise ValueError("stroke points or radii are not finite")
    counts = np.diff(offsets)
    strokes = np.flatnonzero(counts > 0)
    cyclic = np.zeros(len(counts), bool) if cyclic is None else np.asarray(cyclic, dtype=bool).ravel()
    owner = np.repeat(np.arange(len(counts)), counts)
    mean_radius = np.bincount(owner, weights=radii, minlength=len(counts)) / np.maximum(counts, 1)
    radius = np.maximum(mean_radius, min_radius)[strokes]
    if not np.any(radius > 0):
        raise ValueError("the strokes have zero radius: they cover no area")
    # One point strokes are dots; shapely needs two points for a line, so repeat them.
    single = counts[strokes] == 1
    line_points = [points[offsets[i]:offsets[i + 1]] for i in strokes]
    line_points = [np.concatenate([p, p]) if one else p for p, one in zip(line_points, single)]
    # A closed stroke is drawn back to its first point.
    line_points = [np.concatenate([p, p[:1]]) if closed and len(p) > 2 else p
                   for p, closed in zip(line_points, cyclic[strokes])]
    lines = shapely.linestrings(np.concatenate(line_points),
                                indices=np.repeat(np.arange(len(strokes)), [len(p) for p in line_points]))
    parts = []
    if len(areas):
        filled = shape_geometry(areas)
        lines = shapely.difference(lines, filled)
        parts.append(filled)
    sweeps = shapely.buffer(lines, radius, quad_segs=4)
    # A stroke drawn round to where it began covers what it goes round, as a closed one does
    # (QA: the draw tool leaves an outline closed by hand open, and the eyes drawn in it stayed
    # at rest). Holes between strokes stay: an arm drawn against the body leaves a gap there.
    enclosing = np.flatnonzero(shapely.get_num_interior_rings(sweeps) > 0)
    sweeps[enclosing] = shapely.polygons(shapely.get_exterior_ring(sweeps[enclosing]))
    parts.extend(sweeps)
    closed = strokes[cyclic[strokes] & (counts[strokes] >= 3)]
    if len(closed):
        outlines = shapely.linearrings(np.concatenate([points[offsets[i]:offsets[i + 1]] for i in closed]),
                                       indices=np.repeat(np.arange(len(closed)), counts[closed]))
        fills = shapely.make_valid(shapely.polygons(outlines))
        parts.extend(polygonal_part(f) for f in fills)
    union = polygonal_part(shapely.union_all(parts))
    if union.is_empty or union.area <= 0:
        raise ValueError("the strokes cover no area")
    if tolerance is None:
        tolerance = 0.05 * float(radius[radius > 0].min())
    simplified = shapely.simplify(union, tolerance, preserve_topology=True)
    if not simplified.is_empty and simplified.is_valid:
        union = simplified
    return [ring for island in geometry_rings(union) for ring in island]


def image_cutout(image, margin=1.0, level=1.0 / 255.0, tolerance=0.5, window=None, wrap=False):
    """The cut-out of a picture with alpha: its visible pixels, grown by a margin.

    Parameters
    ----------
    image : (H, W, 4) or (H, W) array_like
        Colour with alpha last, or an alpha mask; rows as :func:`solver.trace_silhouette` reads
        them.
    margin : float
        Growth in pixels, so simplification and the rendering's filtering lose no visible pixel.
    level : float
        Alpha at or above which a pixel is visible.
    tolerance : float
        Simplification in pixels.
    window : (k, 2) array_like, optional
        A polygon in pixel units: only the part of the picture inside it is cut out (the part
        a textured plane's UVs show).
    wrap : bool
        The picture repeats (a texture's Extension Repeat): filtering blends each edge with the
        opposite one, so pixels along an edge show the far edge's alpha too.

    Returns
    -------
    list of (k, 2) float64 ndarray
        Rings in pixel units (x along columns, y along rows, one pixel is 1.0), clipped to the
        picture ``[0, W] x [0, H]`` and to ``window``.

    Raises
    ------
    ValueError
        No visible pixel (see :func:`solver.trace_silhouette`), none but specks, or none inside
        ``window``.
    """
    visible = coverage(image)
    alpha = _without_dust(visible, level)
    if not np.any(alpha >= level) and np.any(visible >= level):
        raise ValueError("its only visible pixels are specks, each group holding less ink than one opaque pixel "
                         "(a soft brush's dust), which a cut-out leaves out")
    rings = trace_silhouette(alpha, level=level, tolerance=tolerance, min_area=1.0)
    height, width = alpha.shape
    geometry = shape_geometry(rings)
    if wrap:
        geometry = _with_neighbours(geometry, width, height, margin)
    grown = geometry.buffer(margin, join_style="mitre", mitre_limit=2.0)
    # Simplified before it is clipped: along the picture's edge the clip leaves no margin, and a
    # simplification after it cut a corner off pixels there.
    simplified = shapely.simplify(grown, 0.25 * margin, preserve_topology=True)
    if not simplified.is_empty and simplified.is_valid:
        grown = simplified
    clipped = polygonal_part(shapely.intersection(grown, _frame(width, height, window)))
    if clipped.is_empty:
        raise ValueError("no visible pixel of the picture lies in the part its UVs show")
    return [ring for island in geometry_rings(clipped) for ring in island]


def _with_neighbours(geometry, width, height, margin):
    """``geometry`` with those of its copies a tile over (the picture repeating) that come within
    ``margin`` of the ``width`` x ``height`` picture (QA: the faint pixels they filter in along its
    edges, 50-240 of them, were left out); unchanged where none does."""
    frame = shapely.box(0, 0, width, height)
    reach = 2.0 * margin  # what the grown copy can bring in, and what its simplification can move
    # GEOS does not promise a clip is valid: made so before the union.
    copies = [shapely.make_valid(shapely.clip_by_rect(shapely.affinity.translate(geometry, dx * width, dy * height),
                                                      -reach, -reach, width + reach, height + reach))
              for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy]
    near = [copy for copy in copies if not copy.is_empty and shapely.distance(copy, frame) < margin]
    return shapely.union_all([geometry, *near]) if near else geometry


def shown_frame(width, height, window=None):
    """What a plane shows of a ``width`` x ``height`` picture: its frame clipped to ``window``
    (see :func:`image_cutout`), as rings in pixel units; a cut-out stays inside it."""
    return [ring for island in geometry_rings(_frame(width, height, window)) for ring in island]


def _frame(width, height, window):
    frame = shapely.box(0, 0, width, height)
    if window is None:
        return frame
    return polygonal_part(shapely.intersection(frame, shapely.Polygon(np.asarray(window, dtype=np.float64)).buffer(0)))


def _without_dust(alpha, level):
    """``alpha`` (H, W) with its specks (:func:`specks`) made transparent: nobody sees them (a
    soft brush's or a scan's), and each would otherwise be an island of the cut-out, and of the
    graph."""
    faint = _specks(alpha, level)[1]
    return np.where(faint, 0.0, alpha) if faint.any() else alpha


def _specks(alpha, level):
    """The groups of visible pixels of ``alpha`` (H, W): their labels (H, W) int, and the mask
    (H, W) of those that are specks."""
    labels, count = ndimage.label(alpha >= level, structure=np.ones((3, 3), dtype=bool))
    if count == 0:
        return labels, np.zeros(alpha.shape, dtype=bool)
    ink = ndimage.sum_labels(alpha, labels, index=np.arange(1, count + 1))
    return labels, np.concatenate([[False], ink < 1.0])[labels]


def specks(image, level=1.0 / 255.0, window=None):
    """What :func:`image_cutout` leaves out: each group of visible pixels (at or above ``level``,
    touching by a side or a corner) holding less ink than one opaque pixel.

    Parameters
    ----------
    image : (H, W, 4) or (H, W) array_like
        As :func:`image_cutout` takes it.
    level : float
        Alpha at or above which a pixel is visible.
    window : (k, 2) array_like, optional
        A polygon in pixel units, as :func:`image_cutout` takes it: only groups with a pixel in
        its bounding box count.

    Returns
    -------
    count : int
        How many groups are left out.
    strongest : float
        The highest alpha among their pixels (0.0 when there are none).
    """
    alpha = coverage(image)
    labels, faint = _specks(alpha, level)
    region = (slice(None), slice(None))
    if window is not None:
        box = np.asarray(window, dtype=np.float64)
        (x0, y0), (x1, y1) = np.floor(box.min(axis=0)).astype(int), np.ceil(box.max(axis=0)).astype(int)
        region = (slice(max(y0, 0), max(y1, 0)), slice(max(x0, 0), max(x1, 0)))
    shown = np.unique(labels[region][faint[region]])
    if not len(shown):
        return 0, 0.0
    return len(shown), float(alpha[np.isin(labels, shown)].max())


def map_by_triangles(source, target, triangles, points):
    """Map 2D points by the map that takes each triangle of ``source`` points affinely onto the
    same triangle of ``target`` points: how a face's UVs are interpolated over the triangles
    Blender splits it into. (A quad with a corner moved is no parallelogram: one affine map
    fitted to its four corners put its cut-out's UVs up to 5% of the picture off.)

    Parameters
    ----------
    source, target : (k, 2) array_like
        Corresponding points (a face's corners in two spaces).
    triangles : (t, 3) array_like of int
        Indices into them. A triangle whose source corners lie on one line covers no point and
        is left out.
    points : (p, 2) array_like
        In the space of ``source``. A point outside every triangle follows the one it is least
        outside of (its map extended), so a margin beyond the face stays continuous.

    Returns
    -------
    (p, 2) float64 ndarray

    Raises
    ------
    ValueError
        Every triangle's source corners lie on one line.
    """
    source = np.asarray(source, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    # Each triangle's corners as rows (x, y, 1): a point (x, y, 1) is its barycentric weights
    # times these rows.
    corners = np.concatenate([source[triangles], np.ones((len(triangles), 3, 1))], axis=2)
    size = max(float(np.ptp(source, axis=0).max()) if len(source) else 0.0, 1e-300)
    flat = np.abs(np.linalg.det(corners)) <= 1e-12 * size ** 2 if len(triangles) else np.ones(0, bool)
    if flat.all():
        raise ValueError("the points lie on one line: no affine map is defined")
    corners, triangles = corners[~flat], triangles[~flat]
    weights = np.einsum("pj,tjk->ptk", np.column_stack([points, np.ones(len(points))]), np.linalg.inv(corners))
    chosen = weights.min(axis=2).argmax(axis=1)
    weights = weights[np.arange(len(points)), chosen]
    return np.einsum("pk,pkd->pd", weights, target[triangles[chosen]])
