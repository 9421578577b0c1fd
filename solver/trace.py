"""Silhouettes of bitmaps (paper section 2): marching squares, then simplification.

Pixel ``(row, column)`` of an ``(H, W)`` image covers ``[column, column + 1] x [row, row + 1]``:
x runs along columns, y along rows, one pixel is 1.0. Blender stores image rows bottom-up, so
its pixels traced this way come out the right way up.
"""

from __future__ import annotations

import contourpy
import numpy as np
import shapely

from .shapes import geometry_rings, polygonal_part, shape_geometry

__all__ = ["trace_silhouette", "coverage"]


def coverage(image):
    """How much of each pixel is shape, as a float (H, W) array.

    Parameters
    ----------
    image : (H, W) bool or number array, or (H, W, C) array
        A mask or grey image, or colour with alpha in the last channel (C = 2 or 4): 0 and 1
        (any type), floats from 0 to 1, or uint8 or uint16 over their full range.

    Returns
    -------
    (H, W) float64 ndarray

    Raises
    ------
    ValueError
        An array of another shape, with no pixels, with NaN values, or of another integer
        type with values other than 0 and 1.
    """
    image = np.asarray(image)
    if image.ndim == 3:
        if image.shape[2] not in (2, 4):
            raise ValueError(f"a colour image needs an alpha channel (2 or 4 channels), got {image.shape[2]}")
        image = image[:, :, -1]
    if image.ndim != 2:
        raise ValueError(f"image must be (H, W) or (H, W, C), got shape {image.shape}")
    if min(image.shape) < 1:
        raise ValueError(f"image has no pixels: {image.shape}")
    values = image.astype(np.float64)
    if np.issubdtype(image.dtype, np.integer) and not np.issubdtype(image.dtype, np.bool_) \
            and not np.all((image == 0) | (image == 1)):  # 0 and 1: a mask, whatever its type
        if image.dtype not in (np.uint8, np.uint16):
            raise ValueError(f"an integer image of type {image.dtype} (values {image.min()} to {image.max()}) has "
                             "no full scale: pass a mask of 0 and 1, floats from 0 to 1, or uint8 or uint16 pixels")
        values /= float(np.iinfo(image.dtype).max)
    if not np.all(np.isfinite(values)):
        raise ValueError("image has NaN or infinite values")
    return values


def trace_silhouette(image, level=0.5, tolerance=0.5, max_vertices=None, min_area=4.0):
    """Boundary rings of the pixels at or above ``level``.

    Parameters
    ----------
    image : array_like
        See :func:`coverage`: a mask, a grey image, or colour with alpha.
    level : float
        Coverage threshold, in the same units as a float image (uint8 and uint16 images are
        scaled to [0, 1] first; a mask of 0 and 1 of any type is taken as it is).
    tolerance : float
        Simplification tolerance in pixels (Douglas-Peucker, topology kept). 0 keeps every
        marching-squares vertex.
    max_vertices : int, optional
        Simplify more, if needed, until all rings together have at most this many vertices.
    min_area : float
        Islands and holes smaller than this many pixels are dropped (specks of noise).

    Returns
    -------
    list of (k, 2) float64 ndarray
        Outer rings counter-clockwise, holes clockwise, island by island.

    Raises
    ------
    ValueError
        A malformed image, or no pixel at or above ``level``.
    """
    values = coverage(image)
    # Traced just below the level, so pixels at it count (QA: a picture all of alpha 255 traced
    # at 1 had none).
    below = np.nextafter(level, -np.inf)
    # A border of the emptiest pixel closes every contour, so a shape meets the image's edge as
    # it meets an empty pixel inside (a border below every value pulled a shape touching the
    # edge a sixth of a pixel in), then stops at the edge (_within_picture). Where no pixel is
    # below the level, the border lies as far below it as the most opaque pixel lies above, so
    # the contour runs along the edge.
    empty = values.min()
    if not empty < below:
        empty = min(2.0 * level - values.max(), np.nextafter(below, -np.inf))
    padded = np.pad(values, 1, mode="constant", constant_values=empty)
    lines = contourpy.contour_generator(z=padded, line_type="Separate").lines(below)
    # contourpy places sample (r, c) at (x=c, y=r); pixel centres sit at +0.5, minus the pad.
    rings = [line[:-1] - 0.5 for line in lines if len(line) >= 4]
    if not rings:
        raise ValueError(f"no pixel is as opaque as the level {level:.3g} (is the picture fully transparent?): "
                         "nothing to trace")
    geometry = _within_picture(shape_geometry(rings), values.shape)
    geometry = _drop_specks(geometry, min_area)
    if geometry.is_empty:
        raise ValueError(f"every traced region is smaller than min_area={min_area} pixels")
    simplified = _simplify(geometry, tolerance)
    if max_vertices is not None:
        low, high = tolerance, max(tolerance, 1.0)
        while _vertex_count(simplified) > max_vertices and high < 1e6:
            low, high = high, high * 2.0
            simplified = _simplify(geometry, high)
        for _ in range(30):  # bisect to the finest tolerance that fits the budget
            middle = 0.5 * (low + high)
            candidate = _simplify(geometry, middle)
            if _vertex_count(candidate) <= max_vertices:
                high, simplified = middle, candidate
            else:
                low = middle
    return [ring for island in geometry_rings(simplified) for ring in island]


def _within_picture(geometry, shape):
    """``geometry`` clipped to the picture of ``shape`` (H, W): at a low level a contour meets the
    border half a pixel out (QA: up to 0.5 pixel outside the image)."""
    height, width = shape
    low_x, low_y, high_x, high_y = geometry.bounds
    if low_x >= 0.0 and low_y >= 0.0 and high_x <= width and high_y <= height:
        return geometry  # as traced: a clip would only restart its rings
    return polygonal_part(shapely.intersection(geometry, shapely.box(0.0, 0.0, width, height)))


def _drop_specks(geometry, min_area):
    polygons = []
    for polygon in shapely.get_parts(geometry):
        if polygon.area < min_area:
            continue
        holes = [hole for hole in polygon.interiors if shapely.Polygon(hole).area >= min_area]
        polygons.append(shapely.Polygon(polygon.exterior, holes))
    return shapely.MultiPolygon(polygons) if polygons else shapely.Polygon()


def _simplify(geometry, tolerance):
    if tolerance <= 0:
        return geometry
    simplified = shapely.simplify(geometry, tolerance, preserve_topology=True)
    # Simplification can leave a ring with too few points to bound area; keep the original then.
    return simplified if not simplified.is_empty and simplified.is_valid else geometry


def _vertex_count(geometry):
    return sum(len(ring) for island in geometry_rings(geometry) for ring in island)
