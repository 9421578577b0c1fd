"""How much of a picture its cut-out shows: visible pixels left off the mesh, parts joined.

Run: .venv/bin/python benchmarks/cutout_coverage.py [--seeds 6]

An image plane's cut-out is the rig's graph, whose outline is simplified to the rig's detail.
On seeded random blobby pictures (800 x 600 pixels, smoothed noise, 30% visible, a few hundred
separate parts) at two Graph Densities, for the outline simplified alone and simplified to
cover the picture (``simplify_rings(cover_within=...)``, what Bind does): visible pixels not
wholly on the mesh's triangles, the picture's parts and the mesh's pieces (fewer pieces: parts
joined), and the graph's points. The README quotes the covering rows.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
import shapely
from scipy import ndimage

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from solver.graph import build_graph  # noqa: E402
from solver.outline import simplify_rings, spacing_for_count  # noqa: E402
from solver.rigging.silhouette import image_cutout, shown_frame  # noqa: E402
from solver.shapes import shape_geometry  # noqa: E402

DETAIL = 0.02  # outline_graph's default


def picture(seed, height=600, width=800):
    """Visible pixels (H, W) bool of a smoothed-noise picture, 30% of them visible."""
    noise = ndimage.gaussian_filter(np.random.default_rng(seed).random((height, width)), 6)
    return noise > np.quantile(noise, 0.7)


def measure(visible, density, cover):
    """(pixels off the mesh, the cut-out's parts, the mesh's pieces, graph points)."""
    height, width = visible.shape
    rings = image_cutout(visible.astype(np.float32))
    spacing = spacing_for_count(rings, density)
    within = shown_frame(width, height) if cover else None
    graph = build_graph(simplify_rings(rings, DETAIL * spacing, within), spacing)
    mesh = shapely.union_all(shapely.polygons(graph.points[graph.triangles]))
    rows, columns = np.nonzero(visible)
    off = ~shapely.contains(mesh.buffer(1e-4), shapely.box(columns, rows, columns + 1, rows + 1))
    parts = len(shapely.get_parts(shape_geometry(rings)))
    return int(off.sum()), parts, len(shapely.get_parts(mesh)), graph.n


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=6)
    args = parser.parse_args(argv)
    print("| seed | visible pixels | Graph Density | outline | pixels off the mesh | parts | mesh pieces | graph points |")
    print("|---|---|---|---|---|---|---|---|")
    for seed in range(args.seeds):
        visible = picture(seed)
        for density in (20, 300):
            for cover in (False, True):
                off, parts, pieces, points = measure(visible, density, cover)
                print(f"| {seed} | {int(visible.sum())} | {density} | {'covering' if cover else 'simplified'} "
                      f"| {off} | {parts} | {pieces} | {points} |")


if __name__ == "__main__":
    main()
