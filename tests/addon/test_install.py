# SPDX-License-Identifier: GPL-3.0-or-later
"""The built zip installs like a user's download and registers cleanly."""

import importlib.metadata
import json
import os
import pathlib
import re
import subprocess
import sys
import zipfile

import bpy
import addon_utils
from blender_state import register_cycle
from extension_under_test import ADDON_MODULE, EXTENSION_ID, ROOT, load_build_tool

HERE = os.path.dirname(os.path.abspath(__file__))


def bpy_only_site(dest):
    """Fill ``dest`` with links to bpy and its requirements, nothing else.

    Follows the installed distributions' metadata from ``bpy`` down, so the
    folder holds exactly what Blender-as-a-module needs (numpy included) and
    none of the extension's own dependencies.
    """
    from packaging.requirements import Requirement  # a pytest dependency

    todo, seen = ["bpy"], set()
    while todo:
        dist = importlib.metadata.distribution(todo.pop())
        key = re.sub(r"[-_.]+", "-", dist.metadata["Name"]).lower()
        if key in seen:
            continue
        seen.add(key)
        for line in dist.requires or ():
            req = Requirement(line)
            if req.marker is None or req.marker.evaluate({"extra": ""}):
                todo.append(req.name)
        for top in {f.parts[0] for f in dist.files}:
            src = os.path.join(str(dist.locate_file("")), top)
            dst = os.path.join(dest, top)
            if top != "__pycache__" and not top.endswith(".pth") and os.path.exists(src) \
                    and not os.path.lexists(dst):
                os.symlink(src, dst)
    return seen


def test_zip_holds_every_solver_module(extension_zip):
    # Subpackages too: the add-on imports solver.rigging.
    root = pathlib.Path(ROOT)
    modules = {p.relative_to(root).as_posix() for p in (root / "solver").rglob("*.py")
               if "__pycache__" not in p.parts}
    assert "solver/rigging/__init__.py" in modules
    with zipfile.ZipFile(extension_zip) as zf:
        assert modules - set(zf.namelist()) == set()


def test_zip_installs_and_cycles_without_dev_packages(extension_zip, tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    bundled = sorted(load_build_tool().read_pins())  # distribution = module name for all of them
    dists = bpy_only_site(site)
    assert {"bpy", "numpy"} <= dists and not dists & set(bundled)
    resources = tmp_path / "user-resources"
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env.update(PYTHONPATH=os.pathsep.join([str(site), HERE]), BLENDER_USER_RESOURCES=str(resources))

    # -S: no site-packages of the dev venv, only PYTHONPATH.
    script = os.path.join(HERE, "isolated_install.py")
    proc = subprocess.run([sys.executable, "-S", script, extension_zip, *bundled],
                          env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    report = json.loads(proc.stdout.strip().splitlines()[-1])

    assert report["missing_before"] == bundled
    assert report["install"] == ["FINISHED"]
    assert report["module_file"].startswith(str(resources))
    for name, path in report["dependency_files"].items():
        assert path.startswith(str(resources)), f"{name} not from the bundled wheel: {path}"
    assert report["cycle_problems"] == []
    assert report["enabled_after_cycle"]


def test_addon_fixture_is_the_installed_extension(addon, user_resources):
    assert addon.__name__ == ADDON_MODULE
    assert addon.__file__.startswith(user_resources)
    assert addon_utils.check(ADDON_MODULE) == (True, True)


def test_preferences_are_keyed_by_the_extension_package(addon):
    prefs = bpy.context.preferences.addons[ADDON_MODULE].preferences
    assert type(prefs).bl_idname == addon.__name__ == f"bl_ext.user_default.{EXTENSION_ID}"


def test_addon_survives_scene_reset(addon):
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    assert addon_utils.check(ADDON_MODULE)[1]
    assert len(bpy.data.objects) == 0


def test_register_cycle_leaves_nothing_behind(addon):
    assert register_cycle(ADDON_MODULE) == []
    assert addon_utils.check(ADDON_MODULE)[1]
