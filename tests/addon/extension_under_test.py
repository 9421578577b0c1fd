"""The extension under test: where its checkout is, its id, and the module Blender gives it
once installed (imported by the fixtures and by tests that enable or rebuild it; no bpy here,
so it may be imported before ``conftest`` sets Blender's user folder)."""

import importlib.util
import os

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXTENSION_ID = "shapedeform"
ADDON_MODULE = f"bl_ext.user_default.{EXTENSION_ID}"


def load_build_tool():
    """Import ``tools/build_extension.py`` (``tools`` is not a package)."""
    spec = importlib.util.spec_from_file_location("build_extension", os.path.join(ROOT, "tools", "build_extension.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
