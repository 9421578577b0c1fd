# SPDX-License-Identifier: GPL-3.0-or-later
"""Add-on preferences of the extension."""

import importlib.metadata

import bpy

# Blender keys an extension's preferences by its root package,
# e.g. ``bl_ext.user_default.shapedeform``; this module lives one level below it.
ADDON_ID = __package__.rpartition(".")[0]

# Bundled runtime dependencies, shown so users can check the wheels loaded.
_DEPENDENCIES = ("numpy", "scipy", "shapely", "contourpy", "qdldl")


def dependency_versions():
    """Return the installed version of each runtime dependency.

    Returns
    -------
    dict of str to str
        Distribution name to version, or ``"missing"`` when not installed.
    """
    versions = {}
    for name in _DEPENDENCIES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = "missing"
    return versions


class SHAPEDEFORM_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_ID

    def draw(self, context):
        col = self.layout.column(align=True)
        col.label(text="Bundled libraries:")
        for name, version in dependency_versions().items():
            col.label(text=f"{name} {version}")


classes = (
    SHAPEDEFORM_AP_preferences,
)

register, unregister = bpy.utils.register_classes_factory(classes)
