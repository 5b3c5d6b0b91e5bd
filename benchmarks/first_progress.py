"""When ``pfsdm measure`` first shows progress on a folder of movies (issue 64, point 8).

Run from the repository root::

    .venv/bin/python benchmarks/first_progress.py [FOLDER ...] [--repeats 3]

Each FOLDER (default: the synthetic study's LabA folder, written by
``examples/synthetic_study.py`` into a temporary folder) is measured by ``pfsdm measure
FOLDER -o t.csv`` in a fresh process on a pseudo-terminal (as in a person's terminal, where
the bars redraw every 0.2 s). Timed from the process's start: the first progress bar on
stderr, the frames' bar (``measuring … 0/N``: every movie's frames, shown once the movies are
checked), its first count above 0 (the first task done: the worker processes start first), and
the end. The target: a bar within 2 s, counting the work across all movies (one bar,
not one per movie).
"""

from __future__ import annotations

import argparse
import fcntl
import os
import pty
import re
import select
import statistics
import struct
import subprocess
import sys
import tempfile
import termios
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PFSDM = Path(sys.executable).with_name("pfsdm")


def one_run(folder: Path, out: Path) -> dict[str, float]:
    """Seconds from the start to the first bar, the first counted frame, and the end."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))  # a terminal's size
    start = time.perf_counter()
    proc = subprocess.Popen([str(PFSDM), "measure", str(folder), "-o", str(out), "--force"],
                            stdout=subprocess.DEVNULL, stderr=slave, close_fds=True)
    os.close(slave)
    seen: dict[str, float] = {}
    text = ""
    while True:
        ready, _, _ = select.select([master], [], [], 0.05)
        if ready:
            try:
                chunk = os.read(master, 4096).decode(errors="replace")
            except OSError:
                chunk = ""
            if not chunk and proc.poll() is not None:
                break
            text += chunk
            now = time.perf_counter() - start
            if "it/s" in text or re.search(r"\d+/\d+", text):
                seen.setdefault("bar", now)
            if re.search(r"measuring:[^\r\n]*?\b\d+/\d+", text):
                seen.setdefault("frames", now)
            if re.search(r"measuring:[^\r\n]*?\b([1-9]\d*)/\d+", text):
                seen.setdefault("counted", now)
            text = text[-2000:]
        elif proc.poll() is not None:
            break
    proc.wait()
    os.close(master)
    seen["end"] = time.perf_counter() - start
    if proc.returncode:
        raise SystemExit(f"pfsdm measure {folder} failed ({proc.returncode})")
    return seen


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folders = args.folders
        if not folders:
            sys.path.insert(0, str(ROOT / "examples"))
            from synthetic_study import write_study

            folders = [write_study(Path(tmp) / "study", per_group=6) / "LabA"]
        print("| folder | movies | first bar (s) | the frames' bar (s) | first frames counted (s) "
              "| end (s) |")
        print("|---|---|---|---|---|---|")
        for folder in folders:
            # each run into a new folder: a re-run would skip the movies already measured
            runs = [one_run(folder, Path(tempfile.mkdtemp(dir=tmp)) / "t.csv")
                    for _ in range(args.repeats)]
            med = {k: statistics.median(r.get(k, float("nan")) for r in runs)
                   for k in ("bar", "frames", "counted", "end")}
            n = len([p for p in folder.iterdir() if p.suffix.lower() in (".tif", ".tiff")])
            print(f"| {folder.name} | {n} | {med['bar']:.2f} | {med['frames']:.2f} "
                  f"| {med['counted']:.2f} | {med['end']:.1f} |")
    print(f"\nmedian of {args.repeats} fresh processes on a pseudo-terminal; target: a bar "
          "within 2 s, over every movie.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
