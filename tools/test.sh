#!/usr/bin/env bash
# Set up (or reuse) the environment and run the whole test suite.
#   bash tools/test.sh [pytest args]          Blender 5.0 (Python 3.11)
#   BLENDER=5.1 bash tools/test.sh            Blender 5.1 (Python 3.13)
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/setup_env.sh
echo "Running tests under Blender $BLENDER ($("$PYTHON" --version))"
exec "$PYTHON" -m pytest tests "$@"
