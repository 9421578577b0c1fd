"""Fixtures for the solver tests (the shapes themselves are in ``sample_shapes``)."""

import pytest

import solver
from sample_shapes import hooves_and_head


@pytest.fixture(scope="session")
def horse_rings():
    """scikit-image's horse silhouette (328 x 400 pixels), traced, y up."""
    from skimage.data import horse

    return solver.trace_silhouette(horse()[::-1] == 0, tolerance=1.0)


@pytest.fixture(scope="session")
def horse_graph(horse_rings):
    return solver.build_graph(horse_rings)


@pytest.fixture(scope="session")
def horse_drag(horse_graph):
    """Hooves pinned, head dragged up and back by a third of the horse's size."""
    return hooves_and_head(horse_graph.points)
