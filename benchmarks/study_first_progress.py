"""How soon the study dock's progress moves: the time from the start of a study's measuring
(:func:`napari_pfsdm.napari._study_model.run_study`, what the dock's worker runs) to its first
count of objects, against the whole Run, on 24 synthetic movies (6 frames, 6 objects each).

Run::

    flock /tmp/pfsdm-heavy.lock .venv/bin/python benchmarks/study_first_progress.py
"""

from __future__ import annotations

import time

from napari_pfsdm.napari._study_model import StudyInput, name_groups, run_study
from screenshot_study import movie


def main() -> int:
    movies = {f"c{k % 4}_org{k:02d}": movie(1 + 0.1 * (k % 4), seed=k) for k in range(24)}
    t0 = time.perf_counter()
    first: list = []

    def tick(done: int, total: int, _movie: str) -> None:
        if not first:
            first.append((time.perf_counter() - t0, done, total))

    study = run_study(StudyInput(movies=movies,
                                 name_groups=name_groups(list(movies), "prefix")),
                      progress=tick)
    whole = time.perf_counter() - t0
    at, done, total = first[0]
    print("| movies | rows | first count | whole Run | first / whole |")
    print("|---|---|---|---|---|")
    print(f"| {len(movies)} | {len(study.table)} | {at:.2f} s ({done}/{total} objects) | "
          f"{whole:.1f} s | {at / whole:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
