"""The interior graph: a conforming, counter-clockwise triangulation with MVC-ready neighbours."""

import numpy as np
import pytest

import solver
from solver.energy import mean_value_weights
from sample_shapes import disk, figure_rings, glyph_rings


def triangle_areas(graph):
    a, b, c = (graph.points[graph.triangles[:, k]] for k in range(3))
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


@pytest.mark.parametrize("name", ["disk", "glyph", "horse"])
def test_triangles_tile_the_shape_exactly(name, horse_rings):
    rings = {"disk": [disk()], "glyph": glyph_rings("B&g"), "horse": horse_rings}[name]
    graph = solver.build_graph(rings)
    areas = triangle_areas(graph)
    assert np.all(areas > 0)  # counter-clockwise, none flat
    assert areas.sum() == pytest.approx(graph.area(), rel=1e-9)
    # Every boundary segment is a triangle edge (the triangulation conforms).
    tri_edges = {tuple(sorted(e)) for t in graph.triangles for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    for loop in graph.boundary_loops:
        for i, j in zip(loop, np.roll(loop, -1)):
            assert tuple(sorted((i, j))) in tri_edges
    assert len(graph.interior) > 0 and len(graph.interior) + len(graph.boundary) == graph.n


def test_spacing_controls_density():
    coarse = solver.build_graph([disk()], spacing=0.3)
    fine = solver.build_graph([disk()], spacing=0.1)
    assert len(fine.interior) > 5 * len(coarse.interior)
    default = solver.build_graph([disk()])
    assert 200 <= len(default.interior) <= 500


def test_mean_value_coordinates_reproduce_interior_points(horse_graph):
    adjacency = horse_graph.adjacency()[horse_graph.interior]
    weights = mean_value_weights(horse_graph.points, horse_graph.interior,
                                 adjacency.indices.astype(np.int64), adjacency.indptr.astype(np.int64))
    assert np.all(weights > 0)
    owner = np.repeat(np.arange(len(horse_graph.interior)), np.diff(adjacency.indptr))
    rebuilt = np.zeros((len(horse_graph.interior), 2))
    np.add.at(rebuilt, owner, weights[:, None] * horse_graph.points[adjacency.indices])
    assert np.abs(rebuilt - horse_graph.points[horse_graph.interior]).max() < 1e-9 * horse_graph.size


def test_graph_validation():
    points = np.array([[0, 0], [1, 0], [0, 1], [5, 5]], float)
    with pytest.raises(ValueError, match=r"point 3 has no edges \(1 such point\)"):
        solver.Graph(points, [[0, 1]], [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"point 3 has no edges \(2 such points\)"):
        solver.Graph(np.concatenate([points, [[6, 6]]]), [[0, 1]], [[0, 1, 2]])
    with pytest.raises(ValueError, match="non-finite"):
        solver.Graph(np.full((3, 2), np.nan), [], [[0, 1, 2]])
    with pytest.raises(ValueError, match="do not exist"):
        solver.Graph(points[:3], [[0, 7]], [[0, 1, 2]])
    with pytest.raises(ValueError, match="boundary loop"):
        solver.Graph(points[:3], [], [])


def test_vertices_a_hair_apart_are_merged_and_dense_rings_keep_their_outline():
    """Boolean operations leave ring vertices a hair apart; each would make a triangle of almost
    no area. They are merged; a ring sampled far more densely than the spacing keeps its shape."""
    rings = figure_rings()
    gaps = np.concatenate([np.linalg.norm(r - np.roll(r, 1, axis=0), axis=1) for r in rings])
    assert gaps.min() < 1e-4  # the input has them
    graph = solver.build_graph(rings)
    spacing = solver.graph.default_spacing(solver.shapes.shape_geometry(rings))
    for loop in graph.boundary_loops:
        edges = np.linalg.norm(graph.points[loop] - graph.points[np.roll(loop, 1)], axis=1)
        assert edges.min() >= solver.graph.NEAR_DUPLICATE * spacing
    areas = triangle_areas(graph)
    assert areas.min() > 1e-3 * np.median(areas)
    assert graph.area() == pytest.approx(solver.shapes.shape_geometry(rings).area, rel=1e-4)

    dense = disk(count=20000)  # steps of 3e-4, far below the merge distance
    graph = solver.build_graph([dense], spacing=0.1)
    assert graph.area() == pytest.approx(solver.shapes.shape_geometry([dense]).area, rel=1e-4)


@pytest.mark.parametrize("aspect", [1e-4, 1e-6, 1e-7])
def test_a_sliver_gets_a_bounded_number_of_points(aspect):
    """Its area alone asked for a spacing that lined a bar 1e6 times longer than wide with
    34,644 points (a minute to triangulate; 1e7: over ten minutes)."""
    from solver.graph import DEFAULT_LATTICE_POINTS, MAX_BOUNDARY_SHARE
    bar = [np.array([[0.0, 0.0], [1.0, 0.0], [1.0, aspect], [0.0, aspect]])]
    limit = MAX_BOUNDARY_SHARE * DEFAULT_LATTICE_POINTS + 8
    assert solver.build_graph(bar).n <= limit
    assert solver.outline.outline_graph(bar, DEFAULT_LATTICE_POINTS).n <= limit


def test_shapes_with_a_body_keep_the_spacing_their_area_gives():
    from benchmarks.random_drags import SHAPES
    from solver.graph import DEFAULT_LATTICE_POINTS, default_spacing
    from solver.shapes import shape_geometry
    for name, make in SHAPES.items():
        geometry = shape_geometry(make())
        assert default_spacing(geometry) == pytest.approx(np.sqrt(geometry.area / DEFAULT_LATTICE_POINTS), rel=1e-12), name


@pytest.mark.parametrize("seed", range(4))
def test_the_inset_that_skips_thin_parts_is_the_whole_buffer(seed, horse_rings):
    """The graph's interior comes from the shape shrunk by half a spacing and a spacing. Parts
    that hold no disc of that radius are skipped before shrinking (a scattered picture's specks
    took GEOS seconds); what is left must be exactly what shrinking the whole shape leaves,
    for shapes of many lacy parts and of a few solid ones."""
    import shapely
    from solver.graph import _inset
    from solver.shapes import shape_geometry

    rng = np.random.default_rng(seed)
    mask = np.zeros((120, 160), bool)
    for y, x, h, w in zip(*(rng.integers(0, 110, 300), rng.integers(0, 150, 300),
                            rng.integers(1, 4, 300), rng.integers(1, 4, 300))):
        mask[y:y + h, x:x + w] = True
    mask[20:20 + 10 * seed + 5, 30:70] = True  # one solid block among the specks
    for rings in (solver.trace_silhouette(mask), horse_rings, glyph_rings("B&g")):
        geometry = shape_geometry(rings)
        size = np.ptp(np.concatenate(rings), axis=0).max()
        for distance in size * np.array([0.005, 0.02, 0.05]):
            for style in ({}, {"join_style": "mitre", "mitre_limit": 2.0}):  # as the graph's two insets
                whole = geometry.buffer(-distance, **style)
                inset = _inset(geometry, distance, **style)
                assert shapely.symmetric_difference(whole, inset).area <= 1e-9 * size * size
