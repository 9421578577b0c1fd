# SPDX-License-Identifier: GPL-3.0-or-later
"""benchmarks/options_ab.py: options parsed by their declared types, and two identical sides
measured alike."""

import pytest

import solver
from benchmarks import options_ab


def test_options_are_parsed_by_their_declared_types():
    options = options_ab.parse_options("newton_max_points=0,fold_weight=2.5")
    assert options.newton_max_points == 0 and isinstance(options.newton_max_points, int)
    assert options.fold_weight == 2.5
    assert options_ab.parse_options("") == solver.Options()
    with pytest.raises(ValueError, match="unknown option 'speed'"):
        options_ab.parse_options("speed=11")


def test_identical_sides_reach_the_same_poses(monkeypatch):
    monkeypatch.setattr(options_ab.random_drags, "SHAPES",
                        {"glyph 8": options_ab.random_drags.SHAPES["glyph 8"]})
    same = solver.Options()
    rows = options_ab.compare((same, same), seed=7, drags=1, repeats=2)
    assert len(rows) == 1
    row = rows[0]
    for key in ("error 15", "error 30", "iterations", "ref energy"):
        assert row[0, key] == row[1, key]
    lines = options_ab.report(rows)
    assert lines[-1].startswith("time B / A")
