#!/usr/bin/env bash
# Create or reuse the project's virtual environment; source it or run it.
#
#   BLENDER=4.5:           .venv-4.5  Python 3.11, bpy 4.5.15 (LTS), numpy 1.26.4
#   BLENDER=5.0 (default): .venv      Python 3.11, bpy 5.0.1,        numpy 1.26.4
#   BLENDER=5.1:           .venv-5.1  Python 3.13, bpy 5.1.2,        numpy 2.x
#   BLENDER=5.2:           .venv-5.2  Python 3.13, bpy 5.2.3 (LTS), numpy 2.x
#
# Blender's own pins (bpy, and the numpy that Blender version bundles) live in
# the table below, the one place they are set; everything else comes from
# requirements-dev.txt (which includes requirements-extension.txt). A stamp
# with the hash of both files and the pins makes an existing venv be reused
# until any of them changes. Leaves the venv's interpreter in $PYTHON.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BLENDER="${BLENDER:-5.0}"
case "$BLENDER" in
  4.5) PY_VERSION=3.11; VENV="$ROOT/.venv-4.5"; PINS=(bpy==4.5.15 numpy==1.26.4) ;;
  5.0) PY_VERSION=3.11; VENV="$ROOT/.venv";     PINS=(bpy==5.0.1 numpy==1.26.4) ;;
  5.1) PY_VERSION=3.13; VENV="$ROOT/.venv-5.1"; PINS=(bpy==5.1.2 numpy==2.5.5) ;;
  5.2) PY_VERSION=3.13; VENV="$ROOT/.venv-5.2"; PINS=(bpy==5.2.3 numpy==2.5.5) ;;
  *) echo "setup_env.sh: unsupported BLENDER=$BLENDER (use 4.5, 5.0, 5.1 or 5.2)" >&2; exit 2 ;;
esac

# Find a working pythonX.Y: on PATH, or a pyenv-installed one that is not the
# active pyenv version (its shim on PATH then refuses to run).
find_python() {
  local candidates=("python$1") c
  if command -v pyenv >/dev/null 2>&1; then
    candidates+=("$(pyenv root)"/versions/"$1"*/bin/"python$1")
  fi
  for c in "${candidates[@]}"; do
    if "$c" -c 'import sys' >/dev/null 2>&1; then
      echo "$c"
      return 0
    fi
  done
  echo "setup_env.sh: python$1 not found" >&2
  return 1
}

if ! "$VENV/bin/python" -c 'import sys' >/dev/null 2>&1; then
  echo "setup_env.sh: creating $VENV (Python $PY_VERSION)"
  "$(find_python "$PY_VERSION")" -m venv --clear "$VENV"
fi

STAMP="$VENV/.requirements.sha256"
HASH="$( (cat "$ROOT/requirements-dev.txt" "$ROOT/requirements-extension.txt"; echo "${PINS[@]}") | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$STAMP" 2>/dev/null)" != "$HASH" ]; then
  echo "setup_env.sh: installing requirements-dev.txt into $VENV"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$ROOT/requirements-dev.txt" "${PINS[@]}"
  echo "$HASH" > "$STAMP"
fi

PYTHON="$VENV/bin/python"
export PYTHON
