# SPDX-License-Identifier: GPL-3.0-or-later
"""Install and cycle the extension in a Python that has bpy but not its deps.

Run by ``test_install.py`` as ``python -S isolated_install.py ZIP MODULE...``
(the bundled dependencies to check) with
``PYTHONPATH`` holding only bpy and its own requirements, and
``BLENDER_USER_RESOURCES`` pointing at an empty folder. Prints one JSON line.
"""

import importlib
import importlib.util
import json
import os
import sys

ADDON_MODULE = "bl_ext.user_default.shapedeform"


def main(zip_path, dependencies):
    report = {"missing_before": [m for m in dependencies if importlib.util.find_spec(m) is None]}

    import bpy
    import addon_utils

    from blender_state import blender_state, register_cycle

    report["install"] = sorted(bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo="user_default", enable_on_install=False))
    baseline = blender_state()
    module = addon_utils.enable(ADDON_MODULE, default_set=True)
    report["module_file"] = getattr(module, "__file__", None)
    report["dependency_files"] = {m: importlib.import_module(m).__file__ for m in dependencies}
    report["cycle_problems"] = register_cycle(ADDON_MODULE, baseline=baseline)
    report["enabled_after_cycle"] = addon_utils.check(ADDON_MODULE)[1]
    report["user_resources"] = os.environ["BLENDER_USER_RESOURCES"]
    print(json.dumps(report))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
