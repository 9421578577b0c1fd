"""The README's main job, end to end: tools/demo.py in its own Blender process."""

import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_demo_rigs_bakes_saves_and_draws(tmp_path):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    out = tmp_path / "out"
    result = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "demo.py"), "--out", str(out)],
                            capture_output=True, text=True, timeout=600, env={**os.environ, "TMPDIR": str(scratch)})
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-4000:]
    # Its private Blender user folder (the installed extension, a few hundred MB) is gone.
    assert not list(scratch.iterdir())
    assert "baked frames 1-24" in result.stdout
    for name in ("demo.blend", "demo.png", "monkey.png", "character.png"):
        assert (out / name).stat().st_size > 1000, name
