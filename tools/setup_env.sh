#!/usr/bin/env bash
# Create or reuse the project's virtual environment; source it or run it.
#
#   BLENDER=5.0 (default): .venv      with Python 3.11 and bpy 5.0.x
#   BLENDER=5.1:           .venv-5.1  with Python 3.13 and bpy 5.1.x
#
# Installs requirements-dev.txt (which includes requirements-extension.txt) and
# writes a stamp with their hash, so an existing venv is reused until the
# requirements change. Leaves the venv's interpreter in $PYTHON.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BLENDER="${BLENDER:-5.0}"
case "$BLENDER" in
  5.0) PY_VERSION=3.11; VENV="$ROOT/.venv" ;;
  5.1) PY_VERSION=3.13; VENV="$ROOT/.venv-5.1" ;;
  *) echo "setup_env.sh: unsupported BLENDER=$BLENDER (use 5.0 or 5.1)" >&2; exit 2 ;;
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
HASH="$(cat "$ROOT/requirements-dev.txt" "$ROOT/requirements-extension.txt" | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$STAMP" 2>/dev/null)" != "$HASH" ]; then
  echo "setup_env.sh: installing requirements-dev.txt into $VENV"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$ROOT/requirements-dev.txt"
  echo "$HASH" > "$STAMP"
fi

PYTHON="$VENV/bin/python"
export PYTHON
