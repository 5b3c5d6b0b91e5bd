"""The brain-organoid study: the tutorial's input folder, built from a public data set.

64 human brain organoids of four clones (``wt2D``, ``TH2-7``, ``A1A-1``, ``B2A-2``; 16 each),
each photographed in brightfield (5x objective) on culture days 2, 5, 8, 10, 12 (before and
after embedding, so day 12 twice), 16, 19, 22, 25 and 30, in two laboratories with other
microscopes and pixel sizes (``LabA``: 500 µm = 158 px, ``LabB``: 500 µm = 167 px), and
segmented by the data set's authors with their SegFormer model (one binary mask per image).
Source, citation and licence: :data:`README` (written beside the data).

Two steps, each a run of this script from the repository root:

1. ``--from-clone CLONE`` (once, by whoever sets the data up): take the 1,407 SegFormer masks
   and their catalogue from a checkout of the authors' GitHub repository
   ``deiluca/robust_monitoring_organoid_growth`` into the *source folder* (``--source``,
   default ``../shared/data/brain_organoids`` beside the repository): ``segformer_LabA.npz``
   and ``segformer_LabB.npz`` (every mask unchanged, keyed by its original file name),
   ``images.csv`` (one row per image), the authors' ``LICENSE`` and a ``README.md``; 5.5 MB.
2. (the default) build the tutorial's input folder ``--out`` from the source folder, the way
   a lab keeps a study::

       OUT/LabA/org01.tif … org64.tif   one movie per organoid: (T, Y, X) uint8 labels,
                                        1 = the organoid, 0 = background; ImageJ metadata
                                        with the pixel size in µm and a label per frame
       OUT/LabA/times.csv               movie, frame, time: the culture day of each frame
       OUT/LabB/…                       the same organoids on the second microscope
       OUT/groups.csv                   movie, clone (the same names in both folders)
       OUT/reference_areas.csv          per frame: pixels and µm² by the authors' counts,
                                        the largest piece (scikit-image), border contact
       OUT/LICENSE, OUT/README.md       the authors' licence and where the data come from

The times are uneven (day 12 twice), so they are in ``times.csv`` and not in the movies'
metadata. ``--per-clone N`` keeps the first N organoids of each clone (a quicker study).

Examples
--------
>>> built = build_study("study", per_clone=4)  # doctest: +SKIP
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from napari_pfsdm.errors import InputError
from napari_pfsdm.io.atomic import atomic_write

__all__ = ["LABS", "README", "build_study", "catalogue", "frame_table", "import_clone",
           "main"]

REPO = Path(__file__).resolve().parent.parent
DEFAULT_SOURCE = REPO.parent / "shared" / "data" / "brain_organoids"
SOURCE_REPO = "deiluca/robust_monitoring_organoid_growth"

#: Pixels per 500 µm of each laboratory's 5x images, as the authors' analysis notebook
#: (``data_analysis.ipynb``) converts them: the pixel size is ``500 / n`` µm.
LABS = {"LabA": 158, "LabB": 167}

#: Order of the two images of day 12 (organoids embedded in between).
STAGES = {"": 0, "before_embedding": 0, "after_embedding": 1}

README = """\
# Brain organoids of four clones on two microscopes (SegFormer masks)

Taken from the GitHub repository `deiluca/robust_monitoring_organoid_growth` (commit {commit}),
the code of L. Deininger et al., *A large brain organoid dataset reveals extensive improvement
potential of state-of-the-art analysis pipelines*: its folder `model_predictions/segformer/`
(the authors' SegFormer segmentation of every image) and its table `df_pred.csv`. The images
and the manual annotations themselves are not here: they are on Zenodo (record 10301912,
doi:10.5281/zenodo.10301912), described in Scientific Data (doi:10.1038/s41597-024-03330-z).
Cite the paper and the data set when you use these masks.

Licence: MIT, copyright (c) 2023 Luca Deininger: the repository's licence, in `LICENSE` beside
this file (keep it with any copy).

## What was taken

- `segformer_LabA.npz`, `segformer_LabB.npz`: all {n_masks} masks of
  `model_predictions/segformer/*.npy`, unchanged (boolean, LabA 768 x 1024, LabB 1040 x 1388
  pixels), each under its original file name without `.npy`, e.g. `org01_wt2D_d02_LabA` or
  `org01_wt2D_d12_LabA_before_embedding`. `np.load(file)[name]` gives one mask.
- `images.csv`: one row per image, from `df_pred.csv`: `image`, `organoid` (1-64), `clone`,
  `day` (culture day), `stage` (`before_embedding` / `after_embedding` on day 12, else
  empty), `lab`, `manual_pixels` (area of the manual annotation), `segformer_pixels` (area of
  the mask, checked equal to the mask here) and `segformer_dice` (its overlap with the manual
  annotation, 1 = identical).

## The study

64 organoids, 16 per clone (`wt2D`, `TH2-7`, `A1A-1`, `B2A-2`), each photographed in
brightfield (5x objective) on culture days 2, 5, 8, 10, 12 (before and after embedding), 16,
19, 22, 25 and 30 in two laboratories: LabA (500 um = 158 px, 3.165 um per pixel) and LabB
(500 um = 167 px, 2.994 um per pixel), as the authors' notebook converts them. Organoid 50
(`B2A-2`) has no LabA image of day 12 after embedding: {n_masks} masks, not 1,408.

Caveats: one organoid per image (label 1 across frames is the same organoid); {n_pieces}
masks are in several pieces (segmentation debris beside the organoid; the largest piece is the
organoid); {n_border} masks touch the image border ({border_names}); the masks are a
model's output (median Dice {median_dice:.3f} against the manual annotation), not the manual
annotation.

`examples/study_data.py` of napari-pfsdm made this folder (`--from-clone`) and builds the
tutorial's input folder from it.
"""


# =========================================================================== the source
def _image_parts(name: str) -> dict:
    """Organoid, clone, day, lab and stage from an image name such as
    ``org01_wt2D_d12_LabA_before_embedding``."""
    m = re.fullmatch(r"org(\d+)_(.+)_d(\d+)_(Lab[AB])(?:_(before_embedding|after_embedding))?",
                     name)
    if m is None:
        raise InputError(f"unexpected image name {name!r}: expected e.g. org01_wt2D_d02_LabA")
    return {"organoid": int(m[1]), "clone": m[2], "day": int(m[3]), "lab": m[4],
            "stage": m[5] or ""}


def import_clone(clone: str | Path, source: str | Path) -> dict:
    """Take the SegFormer masks and their catalogue from a checkout of the authors' repository.

    Parameters
    ----------
    clone : str or Path
        A checkout of ``deiluca/robust_monitoring_organoid_growth`` (its work tree).
    source : str or Path
        The folder to fill (created if missing): ``segformer_LabA.npz``, ``segformer_LabB.npz``,
        ``images.csv``, ``LICENSE``, ``README.md``.

    Returns
    -------
    dict
        ``{"masks": n, "pieces": masks in several pieces, "border": masks touching the
        border}``.
    """
    from skimage.measure import label

    clone, source = Path(clone), Path(source)
    folder = clone / "model_predictions" / "segformer"
    if not folder.is_dir() or not (clone / "df_pred.csv").is_file():
        raise InputError(f"{clone} is not a checkout of {SOURCE_REPO}: it has no "
                         "model_predictions/segformer/ folder or no df_pred.csv")
    table = pd.read_csv(clone / "df_pred.csv")
    rows = []
    for _, r in table.iterrows():
        parts = _image_parts(r["img_id"])
        rows.append({"image": r["img_id"], **parts,
                     "manual_pixels": int(r["org_size_px2"]),
                     "segformer_pixels": int(r["pred_SegFormer_org_size"]),
                     "segformer_dice": float(r["pred_SegFormer_dice"])})
    images = pd.DataFrame(rows).sort_values(["lab", "organoid", "day", "stage"], ignore_index=True)
    images = images[["image", "organoid", "clone", "day", "stage", "lab", "manual_pixels",
                     "segformer_pixels", "segformer_dice"]]
    source.mkdir(parents=True, exist_ok=True)
    pieces, border = 0, []
    for lab in LABS:
        masks = {}
        for _, r in images[images["lab"] == lab].iterrows():
            mask = np.load(folder / f"{r['image']}.npy")
            if mask.dtype != bool or int(mask.sum()) != r["segformer_pixels"]:
                raise InputError(f"{r['image']}.npy is not the mask df_pred.csv counts "
                                 f"({mask.dtype}, {int(mask.sum())} pixels, table "
                                 f"{r['segformer_pixels']})")
            pieces += int(label(mask).max() > 1)
            if mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any():
                border.append(r["image"])
            masks[r["image"]] = mask
        atomic_write(source / f"segformer_{lab}.npz",
                     lambda h, m=masks: np.savez_compressed(h, **m), binary=True)
    atomic_write(source / "images.csv", lambda h: images.to_csv(h, index=False))
    shutil.copyfile(clone / "LICENSE", source / "LICENSE")
    text = README.format(commit=_commit(clone), n_masks=len(images), n_pieces=pieces,
                         n_border=len(border), border_names=", ".join(border),
                         median_dice=images["segformer_dice"].median())
    atomic_write(source / "README.md", lambda h: h.write(text))
    return {"masks": len(images), "pieces": pieces, "border": len(border)}


def _commit(clone: Path) -> str:
    """The checkout's commit (``git rev-parse HEAD``), or ``"unknown"`` without git."""
    import subprocess

    try:
        out = subprocess.run(["git", "-C", str(clone), "rev-parse", "HEAD"],
                             capture_output=True, text=True, check=True, timeout=30)
        return out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def catalogue(source: str | Path) -> pd.DataFrame:
    """The source folder's ``images.csv``, with a clear error when the data are not set up."""
    path = Path(source) / "images.csv"
    if not path.is_file():
        raise InputError(
            f"no images.csv in {source}: the brain-organoid data are not set up there. Give "
            "the folder with --source, or make it once from a checkout of the GitHub "
            f"repository {SOURCE_REPO} with --from-clone CHECKOUT")
    images = pd.read_csv(path, dtype={"stage": str}, keep_default_na=False)
    missing = {"image", "organoid", "clone", "day", "stage", "lab"} - set(images.columns)
    if missing:
        raise InputError(f"{path} lacks the columns {', '.join(sorted(missing))}")
    return images


# =========================================================================== the study
def frame_table(images: pd.DataFrame) -> pd.DataFrame:
    """The images of one organoid in one lab in time order, with their frame numbers.

    Day 12 has two images: before embedding (first) and after embedding.
    """
    order = images.assign(_stage=images["stage"].map(STAGES))
    order = order.sort_values(["day", "_stage"], kind="stable").drop(columns="_stage")
    return order.assign(frame=np.arange(len(order))).reset_index(drop=True)


def _movie_name(organoid: int) -> str:
    return f"org{organoid:02d}.tif"


def _frame_label(row: pd.Series) -> str:
    stage = row["stage"].replace("_", " ")
    return f"day {row['day']}" + (f", {stage}" if stage else "")


def _write_movie(path: Path, movie: np.ndarray, pixel_um: float, labels: list[str],
                 info: str) -> None:
    """One label movie as an ImageJ TIFF: axes TYX, pixel size in µm, a label per frame."""
    import io

    import tifffile

    buffer = io.BytesIO()  # tifffile wants a named file or a seekable buffer
    tifffile.imwrite(buffer, movie, imagej=True, compression="zlib",
                     resolution=(1.0 / pixel_um, 1.0 / pixel_um),
                     metadata={"axes": "TYX", "unit": "um", "Labels": labels, "Info": info})
    atomic_write(path, lambda h: h.write(buffer.getvalue()), binary=True)


def _reference_rows(frames: pd.DataFrame, movie: np.ndarray, lab: str, name: str,
                    pixel_um: float) -> list[dict]:
    """Per frame: the authors' pixel counts, the largest piece and border contact."""
    from skimage.measure import label

    rows = []
    for (_, r), mask in zip(frames.iterrows(), movie, strict=True):
        pieces = label(mask > 0)
        sizes = np.bincount(pieces.ravel())[1:]
        rows.append({
            "lab": lab, "movie": name, "frame": int(r["frame"]), "day": int(r["day"]),
            "stage": r["stage"], "pixel_size_um": pixel_um,
            "pixels": int((mask > 0).sum()), "pieces": len(sizes),
            "largest_piece_pixels": int(sizes.max()) if len(sizes) else 0,
            "area_um2": float((mask > 0).sum() * pixel_um ** 2),
            "manual_pixels": r.get("manual_pixels", np.nan),
            "manual_area_um2": r.get("manual_pixels", np.nan) * pixel_um ** 2,
            "segformer_dice": r.get("segformer_dice", np.nan),
            "touches_border": bool(mask[0].any() or mask[-1].any() or mask[:, 0].any()
                                   or mask[:, -1].any()),
        })
    return rows


def build_study(out: str | Path, source: str | Path = DEFAULT_SOURCE, *,
                labs: Sequence[str] = tuple(LABS), per_clone: int | None = None) -> dict:
    """Build the tutorial's input folder from the source folder.

    Parameters
    ----------
    out : str or Path
        Folder to write (created if missing; files of the same names are replaced).
    source : str or Path
        The folder :func:`import_clone` filled.
    labs : sequence of str
        Which acquisitions: ``"LabA"`` (the first microscope), ``"LabB"`` (the second).
    per_clone : int, optional
        Keep the first ``per_clone`` organoids of each clone (by number); all by default.

    Returns
    -------
    dict
        ``{"movies": {lab: [paths]}, "times": {lab: path}, "groups": path,
        "reference": path, "frames": number of frames written}``.
    """
    source, out = Path(source), Path(out)
    images = catalogue(source)
    unknown = sorted(set(labs) - set(LABS))
    if unknown:
        raise InputError(f"unknown lab {', '.join(unknown)}: choose from {', '.join(LABS)}")
    if per_clone is not None and per_clone < 1:
        raise InputError(f"--per-clone must be at least 1, got {per_clone}")
    organoids = images.drop_duplicates("organoid").sort_values("organoid")
    if per_clone is not None:
        organoids = organoids.groupby("clone", sort=False).head(per_clone)
    keep = set(organoids["organoid"])
    out.mkdir(parents=True, exist_ok=True)
    built: dict = {"movies": {}, "times": {}, "frames": 0}
    reference: list[dict] = []
    for lab in labs:
        masks = np.load(source / f"segformer_{lab}.npz")
        pixel_um = 500.0 / LABS[lab]
        (out / lab).mkdir(exist_ok=True)
        times, paths = [], []
        for organoid, own in images[(images["lab"] == lab)
                                    & images["organoid"].isin(keep)].groupby("organoid"):
            frames = frame_table(own)
            name = _movie_name(int(organoid))
            movie = np.stack([masks[n] for n in frames["image"]]).astype(np.uint8)
            clone = frames["clone"].iloc[0]
            _write_movie(out / lab / name, movie, pixel_um, [_frame_label(r) for _, r in
                                                             frames.iterrows()],
                         f"SegFormer masks of brain organoid {organoid} (clone {clone}), "
                         f"{lab}, from {SOURCE_REPO}; MIT licence")
            times += [{"movie": name, "frame": int(r["frame"]), "time": int(r["day"])}
                      for _, r in frames.iterrows()]
            reference += _reference_rows(frames, movie, lab, name, pixel_um)
            paths.append(out / lab / name)
            built["frames"] += len(frames)
        times_path = out / lab / "times.csv"
        atomic_write(times_path, lambda h, t=times: pd.DataFrame(t).to_csv(h, index=False))
        built["movies"][lab], built["times"][lab] = paths, times_path
    groups = pd.DataFrame({"movie": [_movie_name(int(o)) for o in organoids["organoid"]],
                           "clone": organoids["clone"].to_numpy()})
    built["groups"] = atomic_write(out / "groups.csv",
                                   lambda h: groups.to_csv(h, index=False))
    built["reference"] = atomic_write(
        out / "reference_areas.csv", lambda h: pd.DataFrame(reference).to_csv(h, index=False))
    for extra in ("LICENSE", "README.md"):
        if (source / extra).is_file():
            shutil.copyfile(source / extra, out / extra)
    return built


def _summary(built: dict, out: Path) -> str:
    """What was written, in plain words."""
    lines = [f"wrote {out}/"]
    for lab, paths in built["movies"].items():
        size = sum(p.stat().st_size for p in paths) / 1e6
        lines.append(f"  {lab}/  {len(paths)} label movies (org01.tif ...; {size:.1f} MB), "
                     f"pixel size {500.0 / LABS[lab]:.3f} um, times in {lab}/times.csv (days)")
    groups = pd.read_csv(built["groups"])
    counts = ", ".join(f"{c} {n}" for c, n in groups["clone"].value_counts(sort=False).items())
    lines += [f"  groups.csv  {len(groups)} movies: {counts}",
              f"  reference_areas.csv  {built['frames']} frames: pixels, um2, pieces, border",
              "  LICENSE, README.md  the source and its licence (MIT)"]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("brain_organoid_study"),
                    help="the study folder to write (default: brain_organoid_study)")
    ap.add_argument("--source", type=Path, default=DEFAULT_SOURCE,
                    help="the data set's folder (default ../shared/data/brain_organoids "
                         "beside the repository)")
    ap.add_argument("--labs", nargs="+", default=list(LABS), choices=list(LABS))
    ap.add_argument("--per-clone", type=int, default=None, metavar="N",
                    help="the first N organoids of each clone (default: all 16)")
    ap.add_argument("--from-clone", type=Path, default=None, metavar="CHECKOUT",
                    help=f"fill --source from a checkout of {SOURCE_REPO}, then stop")
    args = ap.parse_args(argv)
    try:
        if args.from_clone is not None:
            made = import_clone(args.from_clone, args.source)
            print(f"wrote {args.source}/: {made['masks']} masks ({made['pieces']} in several "
                  f"pieces, {made['border']} touching the border), images.csv, LICENSE, "
                  "README.md")
            return 0
        built = build_study(args.out, args.source, labs=args.labs, per_clone=args.per_clone)
    except InputError as exc:
        print(f"study_data: error: {exc}", file=sys.stderr)
        return 2
    print(_summary(built, args.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
