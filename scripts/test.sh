#!/usr/bin/env bash
# Install what the tests need and run them: ruff, then pytest on a virtual X screen.
#
#   bash scripts/test.sh [extra pytest arguments]
#
# On a fresh Debian (as root) it first installs the system libraries that Qt 6, vispy and the
# virtual X server need (see docs/napari.md). Without root or apt-get it skips that step and
# expects them to be there. Creates .venv (with $PYTHON, default python3) when missing and
# installs the project into it, editable, with the napari, batch and testing extras.
# Exits non-zero as soon as a step fails.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
PYTHON="${PYTHON:-python3}"
START=$(date +%s)
say() { printf '\n== %s (%ds)\n' "$*" "$(( $(date +%s) - START ))"; }

APT_PACKAGES=(xvfb xauth libgl1 libegl1 libgl1-mesa-dri libglib2.0-0 libfontconfig1
  libdbus-1-3 libxkbcommon0 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-image0
  libxcb-keysyms1 libxcb-randr0 libxcb-render-util0 libxcb-shape0 libxcb-xkb1
  chromium)  # the browser tests/test_report.py opens the HTML report in (driven by Playwright)

# wait for another apt-get or unattended upgrade instead of failing at once on its lock
APT_WAIT=(-o DPkg::Lock::Timeout=600)
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  say "system packages (apt-get)"
  export DEBIAN_FRONTEND=noninteractive
  apt-get "${APT_WAIT[@]}" update -qq
  apt-get "${APT_WAIT[@]}" install -y -qq "${APT_PACKAGES[@]}" >/dev/null
else
  say "skipping apt-get (not root or no apt-get); needs: ${APT_PACKAGES[*]}"
fi

if [ ! -x .venv/bin/python ]; then
  say "creating .venv with $PYTHON"
  if ! "$PYTHON" -m venv .venv; then
    # Debian's own python3 needs python3-venv for ensurepip
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
      rm -rf .venv
      apt-get "${APT_WAIT[@]}" install -y -qq python3-venv >/dev/null
      "$PYTHON" -m venv .venv
    else
      echo "error: '$PYTHON -m venv' failed; install python3-venv" >&2
      exit 1
    fi
  fi
fi

say "pip install -e .[testing-gui,batch,tracking] (napari, pyarrow, clusters-plotter, regionprops)"
.venv/bin/python -m pip install -q --disable-pip-version-check -e ".[testing-gui,batch,tracking]"

say "ruff check"
.venv/bin/ruff check .

say "pytest"
unset QT_QPA_PLATFORM  # napari needs a real (virtual) X screen, not the offscreen platform
if command -v xvfb-run >/dev/null 2>&1; then
  xvfb-run -a -s "-screen 0 1280x1024x24" .venv/bin/python -m pytest -p no:xvfb "$@"
elif command -v Xvfb >/dev/null 2>&1; then
  .venv/bin/python -m pytest --xvfb-width=1280 --xvfb-height=1024 --xvfb-colordepth=24 "$@"
elif [ -n "${DISPLAY:-}" ]; then
  .venv/bin/python -m pytest -p no:xvfb "$@"
else
  echo "error: no Xvfb and no DISPLAY: the napari tests need a (virtual) X screen" >&2
  exit 1
fi
# The README's first command installs the core only: run the demo's quick form from a fresh
# virtual environment with `pip install .` (no extras), so that a module the core path needs
# but only an extra installs fails here, not on a new user's machine.
say "demo (quick form) from a fresh core-only install"
CORE_ENV=$(mktemp -d)
trap 'rm -rf "$CORE_ENV"' EXIT
"$PYTHON" -m venv "$CORE_ENV/venv"
"$CORE_ENV/venv/bin/python" -m pip install -q --disable-pip-version-check .
(cd "$CORE_ENV" && "$CORE_ENV/venv/bin/pfsdm" demo --quick-only -o "$CORE_ENV/out")
"$CORE_ENV/venv/bin/python" - "$CORE_ENV/out" <<'PY'
import sys
from pathlib import Path

import pandas as pd

out = Path(sys.argv[1])
for name in ("features.csv", "pca.csv", "distances.csv"):
    table = pd.read_csv(out / name)  # plain CSV: no arguments needed
    assert len(table) > 0 and (out / (name + ".json")).is_file(), name
print("core-only demo: features.csv, pca.csv, distances.csv read by pandas.read_csv()")
PY
say "all tests passed"
