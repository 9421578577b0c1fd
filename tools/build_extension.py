#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Build the Shape Deform extension: one zip per platform.

Usage::

    python tools/build_extension.py [--platforms linux-x64 ...] [--out DIR]
    python tools/build_extension.py --update-manifest

Steps:

1. Download the runtime wheels pinned in ``requirements-extension.txt`` for
   every requested platform and for CPython 3.11 (Blender 4.5-5.0) and 3.13
   (Blender 5.1+) into ``wheels/`` (a git-ignored cache; present files are reused).
2. Stage the extension in a temporary folder whose manifest lists only the
   requested platforms and their wheels, so a single-platform build never needs
   the other platforms' wheels.
3. Build with Blender's own ``blender_ext.py build --split-platforms`` and check
   each zip with ``blender_ext.py validate`` against Blender's tag list.

Must run with a Python that has ``bpy`` installed: Blender's extension tool
ships inside the bpy wheel. ``--update-manifest`` rewrites the ``wheels`` list
of the committed ``blender_manifest.toml`` after the pins change.
"""

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MANIFEST = os.path.join(ROOT, "blender_manifest.toml")
PINS = os.path.join(ROOT, "requirements-extension.txt")
WHEEL_CACHE = os.path.join(ROOT, "wheels")

# CPython of Blender 4.5-5.0 and of Blender 5.1+.
PYTHON_VERSIONS = ("3.11", "3.13")

# pip ``--platform`` tags per Blender platform, most preferred first. pip widens
# macOS tags to older macOS releases by itself but not manylinux tags, so the
# glibc levels are listed. Blender 4.5 needs glibc 2.28 and macOS 11.2; scipy's
# arm64 wheels start at macOS 12. The macOS x86_64 tag is chosen so that pip
# takes the plain ``macosx_*_x86_64`` (OpenBLAS) wheel, which blender_ext maps to
# macos-x64, never the Accelerate build for macOS 14 only.
PIP_PLATFORMS = {
    "linux-x64": ("manylinux_2_28_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64"),
    "windows-x64": ("win_amd64",),
    "macos-arm64": ("macosx_12_0_arm64",),
    "macos-x64": ("macosx_11_0_x86_64",),
}

_OS_FROM_TAG = (("manylinux", "linux"), ("musllinux", "linux"), ("win", "windows"), ("macosx", "macos"))
_ARCH_FROM_TAG = {"x86_64": ("x64",), "amd64": ("x64",), "arm64": ("arm64",), "aarch64": ("arm64",),
                  "universal2": ("x64", "arm64")}


def read_pins(path=PINS):
    """Read ``name==version`` lines.

    Returns
    -------
    dict of str to str
        Normalised distribution name (``-`` as ``_``, lower case) to version.
    """
    pins = {}
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            name, sep, version = line.partition("==")
            if not sep:
                raise SystemExit(f"{path}: pin exact versions (name==version), got {line!r}")
            pins[re.sub(r"[-_.]+", "_", name.strip()).lower()] = version.strip()
    return pins


def parse_wheel_name(filename):
    """Split a wheel file name into its parts.

    Returns
    -------
    tuple
        ``(name, version, python_tag, set of Blender platforms)``; the name is
        normalised like :func:`read_pins` does.
    """
    parts = os.path.basename(filename)[:-len(".whl")].split("-")
    name, version, python_tag, platform_tag = parts[0], parts[1], parts[-3], parts[-1]
    platforms = set()
    for tag in platform_tag.split("."):  # compressed tag sets, e.g. manylinux2014_x86_64.manylinux_2_17_x86_64
        system = next((blender for prefix, blender in _OS_FROM_TAG if tag.startswith(prefix)), None)
        arch = next((archs for suffix, archs in _ARCH_FROM_TAG.items() if tag.endswith(suffix)), ())
        platforms.update(f"{system}-{a}" for a in arch if system)
    return name.lower(), version, python_tag, platforms


def this_platform():
    """Blender's name for this machine's platform, e.g. ``linux-x64``."""
    import platform

    system = {"win32": "windows", "darwin": "macos"}.get(sys.platform, sys.platform)
    machine = platform.machine().lower()
    return f"{system}-{_ARCH_FROM_TAG.get(machine, (machine,))[0]}"


def find_cached_wheel(name, version, python_version, platform, files):
    """Return the cached wheel file name matching one pin, or None."""
    python_tag = "cp" + python_version.replace(".", "")
    for filename in sorted(files):
        if not filename.endswith(".whl"):
            continue
        w_name, w_version, w_python, w_platforms = parse_wheel_name(filename)
        if (w_name, w_version, w_python) == (name, version, python_tag) and platform in w_platforms:
            return filename
    return None


def fetch_wheels(platforms, pins=None, cache=WHEEL_CACHE):
    """Make sure the cache holds every pinned wheel for ``platforms``.

    Only missing wheels are downloaded, with ``pip download --only-binary=:all:
    --no-deps`` for the target platform and Python version.

    Returns
    -------
    list of str
        Wheel file names (inside ``cache``), sorted.
    """
    pins = read_pins() if pins is None else pins
    os.makedirs(cache, exist_ok=True)
    chosen = set()
    for platform in platforms:
        for python_version in PYTHON_VERSIONS:
            def lookup(name, version):
                return find_cached_wheel(name, version, python_version, platform, os.listdir(cache))

            missing = [f"{n}=={v}" for n, v in pins.items() if lookup(n, v) is None]
            if missing:
                print(f"downloading {platform} cp{python_version}: {' '.join(missing)}", flush=True)
                cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
                       "--only-binary=:all:", "--no-deps", "--python-version", python_version,
                       "--implementation", "cp", "--dest", cache]
                for tag in PIP_PLATFORMS[platform]:
                    cmd += ["--platform", tag]
                subprocess.run(cmd + missing, check=True)
            for name, version in pins.items():
                filename = lookup(name, version)
                if filename is None:
                    raise SystemExit(f"no {name}=={version} wheel for {platform} Python {python_version}")
                chosen.add(filename)
    return sorted(chosen)


def blender_ext_paths():
    """Return ``(blender_ext.py, tags.py)`` from the installed bpy."""
    try:
        import bpy  # Imported late: loading Blender takes a second and only the build needs it.
    except ImportError:
        raise SystemExit("bpy is missing: run with the project's venv, e.g. .venv/bin/python "
                         "tools/build_extension.py (bash tools/setup_env.sh creates it)") from None

    scripts = bpy.utils.system_resource("SCRIPTS")
    return (os.path.join(scripts, "addons_core", "bl_pkg", "cli", "blender_ext.py"),
            os.path.join(scripts, "modules", "_bpy_internal", "extensions", "tags.py"))


def _toml_list(values):
    return "[\n" + "".join(f'  "{v}",\n' for v in values) + "]"


def with_list(manifest_text, key, values):
    """Return the manifest text with the top-level array ``key`` replaced."""
    pattern = re.compile(rf"^{key} = \[.*?\]", re.MULTILINE | re.DOTALL)
    if not pattern.search(manifest_text):
        raise SystemExit(f"blender_manifest.toml has no top-level '{key} = [...]'")
    return pattern.sub(lambda _m: f"{key} = {_toml_list(values)}", manifest_text, count=1)


def stage(platforms, wheels, staging):
    """Copy the extension into ``staging`` with a manifest for ``platforms`` only.

    Hidden entries, the wheel cache and the top-level folders that the
    manifest's ``paths_exclude_pattern`` drops anyway (``/name/``) are not
    copied; blender_ext applies the full pattern list when it builds.
    """
    with open(MANIFEST, "rb") as fh:
        manifest = tomllib.load(fh)
    skip_top = {p.strip("/") for p in manifest["build"]["paths_exclude_pattern"]
                if p.startswith("/") and p.endswith("/")}
    skip_top |= {"wheels", "__pycache__"}
    for entry in os.listdir(ROOT):
        src = os.path.join(ROOT, entry)
        if entry.startswith(".") or entry in skip_top or os.path.islink(src):
            continue
        if os.path.isdir(src):
            shutil.copytree(src, os.path.join(staging, entry),
                            ignore=shutil.ignore_patterns("__pycache__", ".*"))
        else:
            shutil.copy2(src, staging)
    os.makedirs(os.path.join(staging, "wheels"))
    for filename in wheels:
        shutil.copy2(os.path.join(WHEEL_CACHE, filename), os.path.join(staging, "wheels"))
    with open(MANIFEST, encoding="utf-8") as fh:
        text = fh.read()
    text = with_list(text, "platforms", platforms)
    text = with_list(text, "wheels", [f"./wheels/{w}" for w in wheels])
    with open(os.path.join(staging, "blender_manifest.toml"), "w", encoding="utf-8") as fh:
        fh.write(text)


def build(platforms=None, out_dir=os.path.join(ROOT, "out", "extension")):
    """Build and validate one extension zip per platform.

    Parameters
    ----------
    platforms : sequence of str, optional
        Blender platform names; defaults to every platform of the manifest.
    out_dir : str
        Where the zips are written (created if missing).

    Returns
    -------
    dict of str to str
        Platform to the path of its zip.
    """
    with open(MANIFEST, "rb") as fh:
        manifest = tomllib.load(fh)
    platforms = list(platforms or manifest["platforms"])
    unknown = sorted(set(platforms) - set(manifest["platforms"]))
    if unknown:
        raise SystemExit(f"unknown platform(s) {unknown}; the manifest lists {manifest['platforms']}")

    pins = read_pins()
    wheels = fetch_wheels(platforms, pins)
    blender_ext, tags = blender_ext_paths()
    os.makedirs(out_dir, exist_ok=True)
    zips = {}
    with tempfile.TemporaryDirectory(prefix="shapedeform-stage-") as staging:
        stage(platforms, wheels, staging)
        _run_blender_ext(blender_ext, "build", "--source-dir", staging, "--output-dir", out_dir,
                         f"--valid-tags={tags}", "--split-platforms")
    for platform in platforms:
        path = os.path.join(out_dir, f"{manifest['id']}-{manifest['version']}-{platform.replace('-', '_')}.zip")
        _run_blender_ext(blender_ext, "validate", f"--valid-tags={tags}", path)
        check_zip_wheels(path, platform, pins)
        zips[platform] = path
        print(f"{path}  {os.path.getsize(path) / 2**20:.1f} MiB", flush=True)
    return zips


def _run_blender_ext(blender_ext, *args):
    """Run blender_ext.py quietly; it reports errors on stdout, so show them on failure."""
    proc = subprocess.run([sys.executable, blender_ext, *args], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"blender_ext.py {args[0]} failed:\n{proc.stdout}{proc.stderr}")


def check_zip_wheels(path, platform, pins):
    """Fail unless the zip holds exactly one wheel per pin and Python version."""
    with zipfile.ZipFile(path) as zf:
        names = [n for n in zf.namelist() if n.endswith(".whl")]
    want = {(n, v, "cp" + p.replace(".", "")) for n, v in pins.items() for p in PYTHON_VERSIONS}
    got = [parse_wheel_name(n) for n in names]
    if sorted((n, v, p) for n, v, p, _ in got) != sorted(want) or any(platform not in w for *_, w in got):
        raise SystemExit(f"{path}: wrong wheels for {platform}: {names}")


def update_manifest():
    """Rewrite the committed manifest's ``wheels`` list from the pins (all platforms)."""
    with open(MANIFEST, "rb") as fh:
        platforms = tomllib.load(fh)["platforms"]
    wheels = fetch_wheels(platforms)
    with open(MANIFEST, encoding="utf-8") as fh:
        text = fh.read()
    new = with_list(text, "wheels", [f"./wheels/{w}" for w in wheels])
    if new != text:
        with open(MANIFEST, "w", encoding="utf-8") as fh:
            fh.write(new)
        print("blender_manifest.toml: wheels list updated")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--platforms", nargs="+", metavar="PLATFORM",
                        help="Blender platforms to build (default: all in the manifest)")
    parser.add_argument("--out", default=os.path.join(ROOT, "out", "extension"),
                        help="output folder (default: out/extension)")
    parser.add_argument("--update-manifest", action="store_true",
                        help="refresh the manifest's wheels list from requirements-extension.txt and exit")
    args = parser.parse_args(argv)
    if args.update_manifest:
        update_manifest()
    else:
        build(args.platforms, os.path.abspath(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
