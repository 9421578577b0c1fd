"""The README's main job, end to end: tools/demo.py in its own Blender process."""

import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_demo_rigs_bakes_saves_and_draws(tmp_path):
    result = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "demo.py"), "--out", str(tmp_path)],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-4000:]
    assert "baked frames 1-24" in result.stdout
    for name in ("demo.blend", "demo.png", "monkey.png", "character.png"):
        assert (tmp_path / name).stat().st_size > 1000, name
