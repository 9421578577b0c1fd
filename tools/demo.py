#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Headless demo of Shape Deform (placeholder).

For now it only checks that Blender-as-a-module and the runtime libraries
load, and prints their versions; the real demo (deforming shapes and writing
``docs/demo.png``-style pictures into ``--out``) replaces this body.
"""

import argparse
import os
import sys


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="out", help="output folder (default: out)")
    args = parser.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)

    import bpy
    import contourpy
    import numpy
    import scipy
    import shapely

    print(f"Blender {bpy.app.version_string}, Python {sys.version.split()[0]}")
    for module in (numpy, scipy, shapely, contourpy):
        print(f"{module.__name__} {module.__version__}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
