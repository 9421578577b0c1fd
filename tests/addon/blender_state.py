# SPDX-License-Identifier: GPL-3.0-or-later
"""Snapshots of what an add-on can register in Blender, to catch leftovers.

Used in-process by the add-on tests and by ``isolated_install.py`` in a
subprocess, so it imports nothing but bpy and addon_utils.
"""

import bpy
import addon_utils  # on sys.path once bpy is loaded


def blender_state():
    """Return what add-ons can leave behind, as plain comparable data.

    Returns
    -------
    dict
        ``types``: RNA properties of every ``bpy.types`` entry (registered
        classes and properties added to Blender types); ``handlers``: the
        functions in each ``bpy.app.handlers`` list; ``keymaps``: items of the
        add-on key configuration; ``addons``: enabled add-on modules.
    """
    types = {}
    for name in dir(bpy.types):
        rna = getattr(getattr(bpy.types, name), "bl_rna", None)
        if rna is not None:
            types[name] = sorted(rna.properties.keys())
    handlers = {
        name: sorted(f"{h.__module__}.{h.__qualname__}" for h in getattr(bpy.app.handlers, name))
        for name in dir(bpy.app.handlers)
        if isinstance(getattr(bpy.app.handlers, name), list)
    }
    keymaps = {}
    keyconfig = bpy.context.window_manager.keyconfigs.addon
    if keyconfig is not None:  # None in some background sessions.
        keymaps = {km.name: sorted(kmi.idname for kmi in km.keymap_items) for km in keyconfig.keymaps}
    addons = sorted(a.module for a in bpy.context.preferences.addons)
    return {"types": types, "handlers": handlers, "keymaps": keymaps, "addons": addons}


def state_difference(before, after):
    """Describe how two :func:`blender_state` snapshots differ (empty if equal).

    Returns
    -------
    list of str
        One line per added, removed or changed entry.
    """
    lines = []
    for section in before.keys() | after.keys():
        a, b = before.get(section), after.get(section)
        if isinstance(a, dict) and isinstance(b, dict):
            for key in sorted(a.keys() | b.keys()):
                if a.get(key) != b.get(key):
                    lines.append(f"{section}[{key!r}]: {a.get(key)!r} -> {b.get(key)!r}")
        elif a != b:
            lines.append(f"{section}: {a!r} -> {b!r}")
    return lines


def register_cycle(module_name, baseline=None):
    """Disable, enable, disable and enable an enabled add-on; report leftovers.

    Parameters
    ----------
    module_name : str
        Full module name, e.g. ``"bl_ext.user_default.shapedeform"``; the
        add-on must be enabled on entry and is enabled again on return.
    baseline : dict, optional
        :func:`blender_state` taken before the add-on was first enabled; when
        given, every disabled state must equal it.

    Returns
    -------
    list of str
        Differences between states that must be equal: both disabled states
        (and the baseline), both enabled states. Empty when registration is clean.
    """
    on_first = blender_state()
    _toggle(module_name, enable=False)
    off_first = blender_state()
    _toggle(module_name, enable=True)
    on_second = blender_state()
    _toggle(module_name, enable=False)
    off_second = blender_state()
    _toggle(module_name, enable=True)
    problems = [f"enabled again: {d}" for d in state_difference(on_first, on_second)]
    problems += [f"disabled again: {d}" for d in state_difference(off_first, off_second)]
    if baseline is not None:
        problems += [f"disabled vs never enabled: {d}" for d in state_difference(baseline, off_first)]
    return problems


def _toggle(module_name, *, enable):
    def fail(ex):
        raise ex

    if enable:
        addon_utils.enable(module_name, default_set=True, handle_error=fail)
    else:
        addon_utils.disable(module_name, default_set=True, handle_error=fail)
