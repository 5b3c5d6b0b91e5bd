"""A synthetic study folder laid out as the tutorial's (docs/tutorial.md): organoids of four
groups, one label movie each, on uneven days, on two microscopes.

For trying the tutorial's commands without the public data set, and for its test::

    python examples/synthetic_study.py --out study [--per-group 4]

writes ``study/LabA/org01.tif …`` (ImageJ TIFFs with the pixel size in µm),
``study/LabA/times.csv`` (movie, frame, day), the same for ``LabB`` (another pixel size) and
``study/groups.csv`` (movie, group) — the layout ``examples/study_data.py`` builds from the
brain-organoid data. The drawing is :func:`napari_pfsdm.data.study.make_study` (known growth
rates and elongations per group).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import tifffile

from napari_pfsdm.data.study import make_study


def write_study(out: str | Path, per_group: int = 4, seed: int = 0) -> Path:
    """Write the study folder (module docstring); returns it."""
    out = Path(out)
    study = make_study(per_group, seed=seed)
    for lab, pixel in study.labs.items():
        folder = out / lab
        folder.mkdir(parents=True, exist_ok=True)
        rows = []
        for name, movie in study.movies[lab].items():
            tifffile.imwrite(folder / f"{name}.tif", movie, imagej=True,
                             resolution=(1.0 / pixel, 1.0 / pixel),
                             metadata={"axes": "TYX", "unit": "um"})
            rows += [f"{name}.tif,{t},{day:g}\n" for t, day in enumerate(study.days)]
        (folder / "times.csv").write_text("movie,frame,time\n" + "".join(rows))
    study.groups.to_csv(out / "groups.csv", index=False)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="study", help="the folder to write (default study)")
    parser.add_argument("--per-group", type=int, default=4, help="organoids per group")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    out = write_study(args.out, args.per_group, args.seed)
    print(f"wrote {out}/: LabA and LabB (label movies, times.csv) and groups.csv")
    return 0


if __name__ == "__main__":
    sys.exit(main())
