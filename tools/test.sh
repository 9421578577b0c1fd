#!/usr/bin/env bash
# Set up (or reuse) the environments and run the whole test suite.
#   bash tools/test.sh [pytest args]             the oldest and newest LTS: Blender 4.5, then 5.2
#   BLENDER=5.0 bash tools/test.sh [pytest args] one version only (4.5, 5.0, 5.1 or 5.2)
# Exits non-zero when any version's run fails; every version runs regardless.
set -uo pipefail
cd "$(dirname "$0")/.."

run_one() {
  (
    set -e
    BLENDER="$1"
    source tools/setup_env.sh
    echo "Running tests under Blender $BLENDER ($("$PYTHON" --version))"
    # The whole suite unless a test path is given (tests/solver, tests/addon/test_bake.py).
    local paths=(tests) arg
    for arg in "${@:2}"; do
      if [[ $arg != -* && -e ${arg%%::*} ]]; then paths=(); fi
    done
    "$PYTHON" -m pytest ${paths[@]+"${paths[@]}"} "${@:2}"
  )
}

if [ -n "${BLENDER:-}" ]; then
  run_one "$BLENDER" "$@"
  exit $?
fi

status=0
summary=()
for version in 4.5 5.2; do
  start=$SECONDS
  run_one "$version" "$@"
  rc=$?
  [ $rc -ne 0 ] && status=1
  summary+=("Blender $version: exit $rc in $((SECONDS - start)) s")
done
printf '%s\n' "${summary[@]}"
exit $status
