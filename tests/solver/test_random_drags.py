# SPDX-License-Identifier: GPL-3.0-or-later
"""The case generator of benchmarks/random_drags.py: seeded, sized, well-formed drags.

Only the cases are checked here, not how well any optimiser converges on them.
"""

import numpy as np
import pytest

from benchmarks import random_drags

SOME = ["glyph 8", "stick figure", "islands"]


@pytest.fixture(scope="module")
def paper_cases():
    return random_drags.cases(7, "paper", drags=2)


def _same(first, second):
    return (first.name == second.name and np.array_equal(first.handles, second.handles)
            and np.array_equal(first.targets, second.targets))


def test_same_seed_same_drags_other_seed_other_drags(paper_cases):
    again = random_drags.cases(7, "paper", shapes=SOME, drags=2)
    mine = [case for case in paper_cases if case.shape in SOME]
    assert all(_same(a, b) for a, b in zip(mine, again))
    other = random_drags.cases(8, "paper", shapes=SOME, drags=2)
    assert not any(np.array_equal(a.targets, b.targets) for a, b in zip(mine, other))


def test_a_drag_does_not_depend_on_what_else_is_asked(paper_cases):
    # Drag 1 of a shape is the same alone, after other shapes, or among more drags.
    alone = random_drags.cases(7, "paper", shapes=["islands"], drags=3)
    listed = next(case for case in paper_cases if case.name == "islands #1")
    assert _same(alone[1], listed)


def test_paper_graphs_are_the_papers_size(paper_cases):
    assert len({case.shape for case in paper_cases}) >= 10
    assert all(400 <= case.graph.n <= 900 for case in paper_cases)


def test_large_graphs_have_about_5000_points():
    # The two whose thin limbs overshoot a lattice-based spacing the most.
    for case in random_drags.cases(7, "5k", shapes=["stick figure", "octopus"], drags=1):
        assert 4000 <= case.graph.n <= 6000


def test_regions_are_disjoint_and_targets_finite(paper_cases):
    for case in paper_cases:
        assert 2 <= len(case.regions) <= 3
        assert all(len(region) >= 3 for region in case.regions)
        assert np.array_equal(case.handles, np.concatenate(case.regions))
        assert len(np.unique(case.handles)) == len(case.handles)
        assert case.targets.shape == (len(case.handles), 2)
        assert np.all(np.isfinite(case.targets))


def test_one_region_is_dragged_and_the_rest_barely_move(paper_cases):
    for case in paper_cases:
        offsets = np.split(case.targets - case.graph.points[case.handles],
                           np.cumsum([len(r) for r in case.regions])[:-1])
        moves = np.array([np.linalg.norm(o, axis=1).max() for o in offsets]) / case.graph.size
        # The dragged disk's centre moves 15-45% of the size; its points also turn about it.
        assert moves[case.moved] > 0.1
        others = np.delete(moves, case.moved)
        assert np.all(others <= random_drags.NUDGE * 1.01)
        assert np.sum(others == 0.0) >= len(others) - 1


def test_random_drag_stays_in_its_ranges():
    import shapely

    square = shapely.box(0.0, 0.0, 1.0, 1.0)
    size = np.sqrt(2.0)
    for index in range(20):
        centres, radii, motions, moved = random_drags.random_drag(np.random.default_rng(index), square)
        m, t = motions[moved]
        shift = np.linalg.norm(centres[moved] @ m.T + t - centres[moved]) / size
        turn = np.degrees(abs(np.arctan2(m[1, 0], m[0, 0])))
        assert 0.15 <= shift <= 0.45 and turn <= 60.0
        assert np.all((radii >= 0.04 * size) & (radii <= 0.06 * size))
        assert all(square.covers(shapely.Point(c)) for c in centres)


def test_libigl_gets_a_point_on_every_loose_island(paper_cases):
    for case in paper_cases:
        if case.shape == "islands":
            handles, targets = random_drags._libigl_handles(case)
            labels = case.graph.components()
            assert set(labels[handles]) == set(labels)
            assert np.array_equal(targets[:len(case.targets)], case.targets)
