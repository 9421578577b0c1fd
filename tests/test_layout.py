# SPDX-License-Identifier: GPL-3.0-or-later
"""House rules of the repository, checked without Blender.

- ``solver/`` stays Blender-free and keeps no module-level caches: a caller that wants to keep
  coarse levels or factors between deformers owns them (``solver.CoarseCopies``).
- ``solver/`` proper (the paper's library) never imports ``solver.rigging`` (the add-on's
  Blender-free helpers); the rigging modules may import ``solver``.
- Add-on code follows the extension rules: no ``bl_info``, no ``sys.path``
  edits, the extension's own packages imported relatively.
- The manifest ships exactly the wheels pinned in ``requirements-extension.txt``.
- The add-on's modules import one another without cycles.
"""

import ast
import importlib.util
import os
import pathlib
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent
BLENDER_MODULES = {"bpy", "bmesh", "mathutils", "bpy_extras"}
OWN_PACKAGES = {"solver", "shapedeform_addon"}


def python_files(*parts):
    return sorted(p for part in parts for p in (ROOT / part).rglob("*.py") if "__pycache__" not in p.parts)


def addon_files():
    return [ROOT / "__init__.py", *python_files("shapedeform_addon")]


def imported_modules(tree):
    """Yield ``(top-level module name, relative level)`` for every import in ``tree``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name.split(".")[0], 0
        elif isinstance(node, ast.ImportFrom):
            yield (node.module or "").split(".")[0], node.level


def parse(path):
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def absolute_imports(path, tree):
    """Yield the dotted name of every module (or module member) ``tree`` imports, relative
    imports resolved against ``path``'s package."""
    package = list(path.relative_to(ROOT).parts[:-1])  # a module's package, or __init__'s own
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            yield from (f"{module}.{alias.name}" for alias in node.names)


def test_solver_does_not_import_blender():
    offenders = [f"{p.relative_to(ROOT)}: {name}"
                 for p in python_files("solver")
                 for name, level in imported_modules(parse(p))
                 if level == 0 and name in BLENDER_MODULES]
    assert offenders == []


def test_solver_proper_does_not_import_rigging():
    offenders = [f"{p.relative_to(ROOT)}: {name}"
                 for p in python_files("solver") if "rigging" not in p.relative_to(ROOT).parts
                 for name in absolute_imports(p, parse(p))
                 if name == "solver.rigging" or name.startswith("solver.rigging.")]
    assert offenders == []


def test_addon_code_has_no_bl_info():
    offenders = [str(p.relative_to(ROOT)) for p in addon_files()
                 for node in ast.walk(parse(p))
                 if isinstance(node, ast.Name) and node.id == "bl_info"]
    assert offenders == []


def test_addon_code_does_not_touch_sys_path():
    offenders = [f"{p.relative_to(ROOT)}:{node.lineno}" for p in addon_files()
                 for node in ast.walk(parse(p))
                 if isinstance(node, ast.Attribute) and node.attr == "path"
                 and isinstance(node.value, ast.Name) and node.value.id == "sys"]
    assert offenders == []


def test_addon_imports_own_packages_relatively():
    offenders = [f"{p.relative_to(ROOT)}: {name}" for p in addon_files()
                 for name, level in imported_modules(parse(p))
                 if level == 0 and name in OWN_PACKAGES]
    assert offenders == []


def load_build_tool():
    spec = importlib.util.spec_from_file_location("build_extension", ROOT / "tools" / "build_extension.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_manifest_wheels_match_the_pins():
    build = load_build_tool()
    pins = build.read_pins()
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text(encoding="utf-8"))
    shipped = {}
    for wheel in manifest["wheels"]:
        name, version, python_tag, platforms = build.parse_wheel_name(wheel)
        assert pins.get(name) == version, f"{wheel} is not pinned in requirements-extension.txt"
        for platform in platforms & set(manifest["platforms"]):
            shipped.setdefault((name, python_tag, platform), []).append(wheel)
    expected = {(name, "cp" + py.replace(".", ""), platform)
                for name in pins for py in build.PYTHON_VERSIONS for platform in manifest["platforms"]}
    assert set(shipped) == expected, "run: python tools/build_extension.py --update-manifest"
    assert all(len(wheels) == 1 for wheels in shipped.values())
    assert "numpy" not in pins, "numpy ships with Blender and must never be bundled"


def test_solver_keeps_no_module_level_containers():
    """A dict, list or set bound at module level in the library is state shared by every caller."""
    containers = (ast.Dict, ast.List, ast.Set, ast.DictComp, ast.ListComp, ast.SetComp)
    offenders = []
    for path in python_files("solver"):
        for node in parse(path).body:
            value = getattr(node, "value", None)
            is_call = isinstance(value, ast.Call) and getattr(value.func, "id", "") in {"dict", "list", "set"}
            targets = [t.id for t in getattr(node, "targets", [getattr(node, "target", None)]) if isinstance(t, ast.Name)]
            if (isinstance(value, containers) or is_call) and targets != ["__all__"]:
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert not offenders, f"module-level containers in solver/: {offenders}"


def addon_module_imports():
    """{add-on module: the add-on modules it imports at its top level}, modules named by their
    path in ``shapedeform_addon`` ("handles", "sources.mesh"; a package by its own name)."""
    package = ROOT / "shapedeform_addon"
    names = {}
    for path in python_files("shapedeform_addon"):
        parts = path.relative_to(package).with_suffix("").parts
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    imports = {}
    for name, path in names.items():
        here = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        found = set()
        for node in ast.parse(path.read_text()).body:
            if not isinstance(node, ast.ImportFrom) or not 0 < node.level <= len(here) + 1:
                continue  # absolute, or above the add-on (``from .. import solver``)
            base = ".".join(here[:len(here) - node.level + 1] + ([node.module] if node.module else []))
            for alias in node.names:  # "from . import x" imports the module x; "from .x import y" the module x
                submodule = f"{base}.{alias.name}".lstrip(".")
                found.add(submodule if submodule in names else base)
        imports[name] = {other for other in found if other in names and other != name}
    return imports


def test_addon_modules_import_one_another_without_cycles():
    imports = addon_module_imports()
    done, path = set(), []

    def visit(module):
        path.append(module)
        for other in sorted(imports[module]):
            assert other not in path, f"import cycle: {' -> '.join(path[path.index(other):] + [other])}"
            if other not in done:
                visit(other)
        path.pop()
        done.add(module)

    for module in sorted(imports):
        if module not in done:
            visit(module)
