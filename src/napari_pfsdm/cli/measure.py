"""``pfsdm measure``: every object of every frame of label movies into one table."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from ..core.params import LINK_OPTION
from .common import (
    UserError,
    add_force,
    check_parts,
    file_argument,
    option_type,
    real_number,
    say,
    whole_number,
    worker_count,
)
from .tables import warn_untracked

#: Frames of one task at most (--frames-per-task): more than any movie holds.
MAX_FRAMES = 1_000_000


def _progress_printer(quiet: bool):
    """A ``progress(stage, done, total, what)`` callback (:func:`~napari_pfsdm.batch.run.
    run_batch`'s) drawing one tqdm bar per stage on stderr, over every movie: the movies
    checked, then the frames measured with the time left; the movie being measured (or what
    the run waits for) after the bar. Redrawn at most every 0.2 s on a terminal, every 5 s
    in a log file; None when quiet."""
    if quiet:
        return None
    from tqdm import tqdm

    bars: dict = {}
    interval = 0.2 if sys.stderr.isatty() else 5.0
    units = {"checking": ("checking movies", "movie"), "measuring": ("measuring", "frame")}

    def show(stage: str, done: int, total: int, what: str) -> None:
        if stage == "close":  # the run ended (or failed): no bar left open before a message
            for other in bars.values():
                other.close()
            return
        bar = bars.get(stage)
        if bar is None:
            for other in bars.values():
                other.close()
            desc, unit = units.get(stage, (stage, "item"))
            bar = bars[stage] = tqdm(total=total, desc=desc, unit=unit, file=sys.stderr,
                                     mininterval=interval, dynamic_ncols=True)
        if what:
            bar.set_postfix_str(what[:40], refresh=False)
        bar.update(done - bar.n)
        if done >= total and total:
            bar.close()

    return show


def _measure_options(args: argparse.Namespace) -> dict[str, Any]:
    """The method options given on the command line (those left out take the defaults)."""
    from ..core.params import OPTIONS

    return {o.name: getattr(args, o.name) for o in OPTIONS
            if getattr(args, o.name, None) is not None}


def _add_method_options(p: argparse.ArgumentParser) -> None:
    """One ``--name`` per option of the record (core.params.OPTIONS): its help, choices and
    default, generated."""
    from ..core.params import OPTIONS

    g = p.add_argument_group(
        "method options (the same as in the napari widget; leave them out for the defaults)"
    )
    only = {"2d": "2-D only: ", "3d": "3-D only: ", "both": ""}
    for opt in OPTIONS:
        kw: dict[str, Any] = {"dest": opt.name, "type": option_type(opt),
                              "help": f"{only[opt.dims]}{opt.help} (default {opt.default})"}
        if opt.choices:
            kw["choices"] = opt.choices
        else:
            kw["metavar"] = "N" if opt.kind is int else "X"
        g.add_argument(opt.flag, **kw)


def _add_compute_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("where the work runs")
    g.add_argument("--scheduler", default="processes", metavar="WHERE",
                   help="'processes' (default: one process per core of this machine), "
                        "'threads', 'sync' (one at a time, for debugging), or the address of a "
                        "dask scheduler to run on a cluster, e.g. tcp://10.0.0.5:8786")
    g.add_argument("--workers", type=worker_count("--workers"), metavar="N",
                   help="local workers, at most the number of cores (default: one per core)")
    g.add_argument("--frames-per-task", dest="frames_per_task",
                   type=whole_number("--frames-per-task", 1, MAX_FRAMES), metavar="N",
                   help="whole frames measured per task (default: tasks planned by objects, "
                        "as the local process pool plans them)")


def _parts_folder(args: argparse.Namespace) -> list:
    """The default parts folder, an output of its own (``--parts`` when not given)."""
    from ..batch.run import default_parts_dir
    from ..io import Output

    if args.parts is not None or not args.output:
        return []
    return [Output(default_parts_dir(args.output), "folder", "parts folder (--parts)")]


def cmd_measure(args: argparse.Namespace) -> int:
    """Run ``pfsdm measure``: the label movies measured into one feature table."""
    from ..analysis.features import warnings_summary
    from ..batch.movies import find_movies, pair_movies
    from ..batch.run import default_parts_dir, rows_words

    if not args.labels:
        if args.intensity and len(args.intensity) > 1:
            raise UserError(
                f"no label movie given: -i/--intensity took all of {' '.join(args.intensity)}. "
                "Put the labels first, e.g.: pfsdm measure labels.tif -i reporter.tif "
                "-o features.csv"
            )
        raise UserError("give the label movie(s) to measure, e.g.: pfsdm measure labels.tif "
                        "-o features.csv")
    from ..core.params import PFSDMParams

    params = PFSDMParams.from_options(_measure_options(args))  # fails before any file opens
    if args.axes is not None and args.axes.lower() not in ("yx", "tyx", "zyx", "tzyx"):
        raise UserError(f"--axes must be yx, tyx, zyx or tzyx (t time, z y x space); got "
                        f"{args.axes!r}")
    if args.axes is not None:
        args.axes = args.axes.lower()
    if args.spacing is not None and args.axes not in ("zyx", "tzyx"):
        raise UserError("--spacing is for 3-D objects: say which axes the files have, "
                        "--axes zyx (a Z-stack) or --axes tzyx (a time-lapse of Z-stacks)")
    if args.axes is not None:
        params.check_dimension(3 if "z" in args.axes else 2)
    labels = find_movies(args.labels)
    intensity = find_movies(args.intensity) if args.intensity else None
    out = Path(args.output)  # checked with the inputs before the command ran (cli.main)
    check_parts(Path(args.parts) if args.parts else default_parts_dir(out))
    movies = pair_movies(labels, intensity)
    say(f"measuring {len(movies)} movie(s) -> {out}", args.quiet)
    t0 = time.perf_counter()
    progress = _progress_printer(args.quiet)
    try:
        table = _measured_table(args, movies, out, params, progress)
    finally:
        if progress is not None:
            progress("close", 0, 0, "")
    dt = time.perf_counter() - t0
    say(f"wrote {out} (options in {out.name}.json): {rows_words(table)} from "
         f"{len(movies)} movie(s) in {dt:.1f} s", args.quiet)
    summary = warnings_summary(table)
    if summary:
        say(summary[0].upper() + summary[1:], args.quiet)
    if args.link == "labels":
        warn_untracked(table, args.quiet)
    parts = Path(args.parts) if args.parts else default_parts_dir(out)
    say(f"per-movie parts kept in {parts} (a re-run skips finished movies)", args.quiet)
    return 0


def _measured_table(args: argparse.Namespace, movies, out: Path, params, progress):
    """``run_batch`` with the command line's options."""
    from ..batch.run import run_batch

    return run_batch(
        movies, out,
        scheduler=args.scheduler, num_workers=args.workers,
        frames_per_task=args.frames_per_task,
        parts_dir=args.parts,
        progress=progress,
        log=lambda m: say("  " + m, args.quiet),
        allow_empty=args.allow_empty,
        params=params,
        link=args.link,
        axes=args.axes,
        spacing=args.spacing,
        allow_missing_chunks=args.allow_missing_chunks,
        series=args.series,
        times=_times(args.times),
        time_unit=args.time_unit,
        pixel_size=args.pixel_size,
        space_unit=args.space_unit,
        reporter_channel=args.reporter_channel,
    )


def _times(text: str | None) -> Any:
    """``--times``: a comma-separated list (every movie's frames), or a CSV file with the
    columns movie, frame, time."""
    from ..batch.calibration import read_times_file

    if text is None:
        return None
    if Path(text).is_file():
        return read_times_file(text)
    try:
        return [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
    except ValueError:
        raise UserError(f"--times must be numbers separated by commas (e.g. --times "
                        f"2,5,8,10) or a CSV file (movie, frame, time); got {text!r}, which "
                        "is neither") from None


def _reporter_channel(text: str) -> int:
    """``--reporter-channel``: a whole number from 0 to the most channels a reporter may have
    (``analysis.label_images.MAX_CHANNELS``, the plugin's)."""
    from ..analysis.label_images import MAX_CHANNELS

    return whole_number("--reporter-channel", 0, MAX_CHANNELS - 1)(text)


def _series_index(text: str) -> int:
    """``--series``: a whole number (negative counts from the last series)."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--series must be a whole number (0 = the first series); got {text!r}") from None


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``pfsdm measure`` to ``sub`` (the subcommands of
    :func:`~napari_pfsdm.cli.build_parser`, or the demo's own), ``cmd_*`` as its ``func``; the
    method's options generated from the one record (``core.params.OPTIONS``)."""
    fmt = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(
        "measure", formatter_class=fmt,
        help="measure the shape (and reporter) of every object in label movies",
        description="""\
Measure every object of every frame of label movies into one CSV table.

LABELS are segmentations: each object one whole number, 0 = background; a 2-D image (Y, X) or
a time-lapse (T, Y, X). Give TIFF files (.tif/.tiff), Zarr arrays (.zarr) or OME-Zarr images
(the full-resolution level is read), a folder of these, or a glob such as 'plate1/*.tif'
(quote it). Several movies give one table with a 'movie' column (the file name).

The optional --intensity images (e.g. a Brachyury::mCherry reporter) must have the same size
as the labels; with several movies they pair by name: movie01_labels.tif <-> movie01_intensity.tif.

Long runs can be resumed: each finished movie is saved in FEATURES.csv.parts/; run the same
command again after an interruption and finished movies are skipped.

Objects are followed over time: labels from per-frame segmentation (cellpose, StarDist), whose
ids change between frames, are detected and linked by their centroids into a track_id
column (--link; 'pfsdm trajectories' follows it). Labels that already follow the
objects (from a tracker) are kept as they are.

examples:
  pfsdm measure embryo01_labels.tif --intensity embryo01_reporter.tif -o features.csv
  pfsdm measure 'plate1/*_labels.zarr' --intensity 'plate1/*_reporter.zarr' -o plate1.csv
  pfsdm measure archive/ -o archive.csv --scheduler tcp://10.0.0.5:8786
""")
    # "*" rather than "+": a labels file swallowed by -i gets a message that says so
    file_argument(p, "labels", role="input", kind="movie", name="label movie", nargs="*",
                  metavar="LABELS",
                  help="label movie(s): TIFF, Zarr or OME-Zarr files, folders or globs")
    file_argument(p, "-i", "--intensity", role="input", kind="movie", nargs="+",
                  metavar="IMAGE", help="reporter movie(s) of the same size as the labels")
    p.add_argument("--reporter-channel", dest="reporter_channel", metavar="N",
                   type=_reporter_channel,
                   help="the channel of reporters with several (an axis more than the labels: "
                        "T, C, Y, X), as the napari plugin offers each channel (0 = the first)")
    file_argument(p, "-o", "--output", role="output", kind="table", required=True,
                  metavar="FEATURES.csv",
                   help="the feature table to write (plain CSV; the options go into "
                        "FEATURES.csv.json beside it: keep the two together). A name "
                        "ending in .parquet writes Parquet (faster for large tables; pip "
                        "install \"napari-pfsdm[parquet]\"), which every command reads too")
    p.add_argument("--allow-empty", dest="allow_empty", action="store_true",
                   help="write an empty table when the labels hold no object (default: an "
                        "error, as labels with only background are usually the wrong file)")
    p.add_argument("--allow-missing-chunks", dest="allow_missing_chunks", action="store_true",
                   help="measure Zarr movies whose chunk files are not all on disk, reading "
                        "the missing ones as the fill value (empty), with a warning per frame "
                        "(default: an error, as a store that lost files in a copy looks "
                        "just the same)")
    p.add_argument("--series", type=_series_index, metavar="N",
                   help="the image series to read from TIFF files that hold several (OME-TIFF "
                        "positions, a thumbnail beside the image; 0 = the first); such a file "
                        "is refused without it")
    add_force(p)
    p.add_argument("--link", choices=LINK_OPTION.choices, default=LINK_OPTION.default,
                   help=LINK_OPTION.help + " (a track_id column that trajectories follow; "
                        "'laptrack' needs pip install laptrack; with 'labels' a warning says "
                        "when the labels look untracked)")
    file_argument(p, "--parts", role="output", kind="folder", metavar="DIR",
                   help="folder for per-movie results (default: FEATURES.csv.parts)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or messages")
    gu = p.add_argument_group(
        "time and size (read from the files' metadata when they have them: ImageJ, OME, TIFF "
        "resolution, OME-Zarr; given values win)")
    gu.add_argument("--times", metavar="T1,T2,… | TIMES.csv",
                    help="each frame's time, the same for every movie (e.g. --times "
                         "2,5,8,10,12,12,16 for culture days; a time may repeat), or a CSV "
                         "with the columns movie, frame, time: the table gets a time column")
    gu.add_argument("--time-unit", metavar="UNIT",
                    help="the times' unit: s, min, h or day (the files' times are converted "
                         "to it)")
    gu.add_argument("--pixel-size", nargs="+", type=real_number("--pixel-size", 1e-6, 1e6),
                    metavar="SIZE",
                    help="the size of a pixel (one number: square pixels; Z Y X for "
                         "Z-stacks): areas, lengths, widths and perimeters are then in "
                         "--space-unit (shape features have no unit)")
    gu.add_argument("--space-unit", metavar="UNIT",
                    help="the pixel size's unit: nm, um (default), mm (the files' pixel "
                         "sizes are converted to it)")
    g3 = p.add_argument_group("3-D objects (Z-stacks)")
    g3.add_argument("--axes", metavar="AXES",
                    help="which axes the label files have: yx, tyx (a time-lapse of 2-D "
                         "frames: the default for 3-D files), zyx (one Z-stack of 3-D objects) "
                         "or tzyx (a time-lapse of Z-stacks; 4-D files must say so)")
    g3.add_argument("--spacing", nargs=3, type=float, metavar=("Z", "Y", "X"),
                    help="voxel size along Z, Y and X, e.g. --spacing 2 0.5 0.5 (µm); only "
                         "with --axes zyx or tzyx (default 1 1 1)")
    _add_method_options(p)
    _add_compute_options(p)
    p.set_defaults(func=cmd_measure, pfsdm_derived=_parts_folder)
