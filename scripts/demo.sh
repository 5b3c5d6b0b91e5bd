#!/usr/bin/env bash
# Install napari-pfsdm into .venv (created when missing) and run the demo on synthetic data:
# the feature tables, trajectories, distances and classification land in ./results.
#
#   bash scripts/demo.sh [output folder]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PYTHON="${PYTHON:-python3}"
OUT="${1:-results}"
if [ ! -x .venv/bin/python ] && ! "$PYTHON" -m venv .venv; then
  # Debian's own python3 needs python3-venv for ensurepip
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    rm -rf .venv
    apt-get update -qq && apt-get install -y -qq python3-venv >/dev/null
    "$PYTHON" -m venv .venv
  else
    echo "error: '$PYTHON -m venv' failed; install python3-venv" >&2
    exit 1
  fi
fi
.venv/bin/python -m pip install -q --disable-pip-version-check -e .
.venv/bin/pfsdm demo -o "$OUT"
echo "demo results in $OUT/"
