#!/usr/bin/env bash
# Install napari-pfsdm (the core, no extras) into .venv (created when missing) and run the demo
# on bundled synthetic data: the feature tables, trajectories, distances and classification
# land in ./results.
#
#   bash scripts/demo.sh [output folder] [pfsdm demo options, e.g. --quick-only]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PYTHON="${PYTHON:-python3}"
OUT="${1:-results}"
shift || true
if [ ! -x .venv/bin/python ] && ! "$PYTHON" -m venv .venv; then
  # Debian's own python3 needs python3-venv for ensurepip
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    rm -rf .venv
    apt-get -o DPkg::Lock::Timeout=600 update -qq \
      && apt-get -o DPkg::Lock::Timeout=600 install -y -qq python3-venv >/dev/null
    "$PYTHON" -m venv .venv
  else
    echo "error: '$PYTHON -m venv' failed; install python3-venv" >&2
    exit 1
  fi
fi
echo "== installing napari-pfsdm into .venv (1-3 minutes on a fresh machine) ==" >&2
# pip's own progress, less the "already satisfied" lines of a re-run; a failed pip stops here
.venv/bin/python -m pip install --disable-pip-version-check -e . 2>&1 \
  | { grep --line-buffered -v '^Requirement already satisfied' || true; }
.venv/bin/pfsdm demo -o "$OUT" "$@"
echo "demo results in $OUT/"
