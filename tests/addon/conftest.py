# SPDX-License-Identifier: GPL-3.0-or-later
"""Fixtures for add-on tests, run under PyPI ``bpy``.

Fixtures
--------
addon
    The extension as a user gets it: the zip built from this checkout by
    ``tools/build_extension.py``, installed with Blender's own installer into
    a private user-resources folder and enabled; the fixture returns the
    module ``bl_ext.user_default.shapedeform`` and makes sure it is enabled
    when the test starts. Use it in every test that needs the add-on.
extension_zip
    Path of the zip for this machine's platform (built once per session).
user_resources
    The private ``BLENDER_USER_RESOURCES`` folder of the session.
empty_scene (autouse)
    Every test starts from Blender's empty factory scene.

Blender reads ``BLENDER_USER_RESOURCES`` while ``bpy`` loads (for instance to
put the extensions' wheel folder on ``sys.path``), so it is set here, when
pytest imports this file and before anything imports ``bpy``. Tests must not
import ``bpy`` from outside ``tests/addon``.
"""

import os
import shutil
import sys
import tempfile

import pytest

if "bpy" in sys.modules:
    raise RuntimeError("bpy was imported before tests/addon/conftest.py could set BLENDER_USER_RESOURCES")

USER_RESOURCES = tempfile.mkdtemp(prefix="shapedeform-user-resources-")
os.environ["BLENDER_USER_RESOURCES"] = USER_RESOURCES

import bpy  # noqa: E402  (needs the environment above)
import addon_utils  # noqa: E402  (on sys.path once bpy is loaded)

from extension_under_test import ADDON_MODULE, load_build_tool  # noqa: E402


def fail_on_error(ex):
    """``handle_error`` for addon_utils: raise instead of printing and going on."""
    raise ex


def pytest_sessionfinish(session, exitstatus):
    shutil.rmtree(USER_RESOURCES, ignore_errors=True)


@pytest.fixture(scope="session")
def user_resources():
    """The session's private user-resources folder (removed when pytest ends)."""
    return USER_RESOURCES


@pytest.fixture(scope="session")
def extension_zip(tmp_path_factory):
    """Build this platform's extension zip once per session and return its path."""
    build_tool = load_build_tool()
    platform = build_tool.this_platform()
    return build_tool.build([platform], str(tmp_path_factory.mktemp("extension")))[platform]


@pytest.fixture(scope="session")
def installed_extension(user_resources, extension_zip):
    """Install the zip like a user (Blender's installer) and enable it, once."""
    assert bpy.utils.user_resource("EXTENSIONS").startswith(user_resources)
    result = bpy.ops.extensions.package_install_files(
        filepath=extension_zip, repo="user_default", enable_on_install=False)
    assert result == {"FINISHED"}
    module = addon_utils.enable(ADDON_MODULE, default_set=True, handle_error=fail_on_error)
    assert module is not None, f"could not enable {ADDON_MODULE}"
    yield module
    addon_utils.disable(ADDON_MODULE, default_set=True)


@pytest.fixture
def addon(installed_extension):
    """The installed extension's module, enabled (re-enabled if a test disabled it)."""
    if not addon_utils.check(ADDON_MODULE)[1]:
        addon_utils.enable(ADDON_MODULE, default_set=True, handle_error=fail_on_error)
    return sys.modules[ADDON_MODULE]


@pytest.fixture(autouse=True)
def empty_scene():
    """Start each test from the empty factory scene (enabled add-ons stay enabled)."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    yield


@pytest.fixture
def quiet(capfd):
    """Fails the test when anything printed a traceback (an exception in a handler is only
    printed by Blender, never raised to the caller)."""
    yield
    out, err = capfd.readouterr()
    assert "Traceback" not in out + err, out + err
