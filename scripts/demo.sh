#!/usr/bin/env bash
# Install napari-pfsdm into .venv (created when missing) and run the demo on synthetic data:
# the feature tables, trajectories, distances and classification land in ./results.
#
#   bash scripts/demo.sh [output folder]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PYTHON="${PYTHON:-python3}"
OUT="${1:-results}"
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install -q --disable-pip-version-check -e .
.venv/bin/pfsdm demo -o "$OUT"
echo "demo results in $OUT/"
