"""Run a script that has no ``if __name__ == "__main__":`` guard (imported by the tests)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

#: What the script prints first: worker processes that re-ran it would print it again.
BODY = "script body runs"


def run_once(folder: Path, lines: list[str]) -> str:
    """Write ``lines`` as a script without a main guard in ``folder``, run it in a new Python,
    check that it succeeded and that its body ran once (in this process only, not again in a
    worker process), and return what it printed."""
    script = folder / "no_guard.py"
    script.write_text(f"print({BODY!r}, flush=True)\n" + "\n".join(lines) + "\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count(BODY) == 1
    return done.stdout
