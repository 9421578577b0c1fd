#!/usr/bin/env bash
# Set up (or reuse) the environment and run the headless demo into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/setup_env.sh
exec "$PYTHON" tools/demo.py --out out/ "$@"
