"""``pfsdm demo``: the whole analysis on bundled synthetic data.

The two reports it starts with (the five-shape benchmark, the gastruloid axis-number report)
are the paper's reproductions in the ``examples/`` folder of a napari-pfsdm checkout, which is
not installed with the package: the demo runs them when the package runs from a checkout (an
editable install, as ``scripts/demo.sh`` makes) and says it skipped them otherwise. The
time-lapse part runs ``pfsdm measure``, ``pfsdm trajectories`` and ``pfsdm compare`` through
the commands' own functions.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path
from types import ModuleType

from . import compare, trajectories
from .common import UserError, add_force, check_command_files, file_argument, say

#: The reports the demo runs first: (title, module of the checkout's ``examples/`` folder).
EXAMPLES = (
    ("synthetic five-shape benchmark", "synthetic_five_shapes"),
    ("gastruloid axis-number report", "gastruloid_report"),
)


def examples_folder() -> Path | None:
    """The ``examples/`` folder of the checkout the package runs from.

    Returns
    -------
    pathlib.Path or None
        The folder beside ``src/`` when the package is imported from a checkout (an editable
        install); None for an installed copy of the package, which has none.
    """
    folder = Path(__file__).resolve().parents[3] / "examples"
    return folder if folder.is_dir() else None


def load_example(name: str) -> ModuleType:
    """Import the module ``examples/<name>.py`` of the checkout.

    Parameters
    ----------
    name : str
        The module's name, e.g. ``"gastruloid_report"``.

    Returns
    -------
    types.ModuleType
        The module (its folder is on ``sys.path`` while it is imported, so that it finds the
        modules beside it).

    Raises
    ------
    ImportError
        When the package does not run from a checkout with that module.
    """
    folder = examples_folder()
    if folder is None or not (folder / f"{name}.py").is_file():
        raise ImportError("the package does not run from a napari-pfsdm checkout, whose "
                          "examples/ folder holds it; run the demo from a checkout: bash "
                          "scripts/demo.sh", name=name)
    sys.path.insert(0, str(folder))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(folder))


#: The files the time-lapse part of the demo writes into its folder, and what each is.
DEMO_FILES = (("montage_labels.tif", "file"), ("montage_intensity.tif", "file"),
              ("groups.csv", "table"), ("features.csv", "table"),
              ("features.csv.parts", "folder"), ("pca.csv", "table"), ("pca.png", "plot"),
              ("distances.csv", "table"), ("mds.png", "plot"))


def demo_outputs(out: Path, examples: bool = True) -> list:
    """Every file the demo writes into ``out`` (:class:`napari_pfsdm.io.Output`): its own
    (:data:`DEMO_FILES`) and, with ``examples``, those each report of :data:`EXAMPLES`
    declares (its ``OUTPUT_FILES``), all checked before any work."""
    from ..io import Output

    files = [Output(out / name, kind, "demo's output") for name, kind in DEMO_FILES]
    for _title, name in EXAMPLES if examples else ():
        try:
            mod = load_example(name)
        except ImportError:
            continue  # skipped, and said so, when the demo runs
        files += [Output(out / f, "table" if f.endswith(".csv") else "plot", "demo's output")
                  for f in mod.OUTPUT_FILES]
    return files


def _run_examples(out: Path) -> list[str]:
    """Run the reports of :data:`EXAMPLES` (quick) into ``out``; the titles of those that
    failed (the demo goes on without them)."""
    failed = []
    for title, name in EXAMPLES:
        try:
            mod = load_example(name)
        except ImportError as exc:
            say(f"== {title} ==")
            say(f"   skipped: examples/{name}.py is not available ({exc})")
            continue
        say(f"== {title} (examples/{name}.py) ==")
        try:
            mod.run(out, quick=True)
        except Exception as exc:  # keep going: the other parts of the demo still run
            print(f"pfsdm: warning: {title} failed: {type(exc).__name__}: {exc}",
                  file=sys.stderr)
            failed.append(title)
    return failed


def _command_args(module: ModuleType, argv: list[str]) -> argparse.Namespace:
    """``argv`` (the command's name first) parsed by the parser the command's module
    declares: its defaults and checks, as on the command line."""
    parser = argparse.ArgumentParser(prog="pfsdm")
    module.add_parser(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def _run_command(module: ModuleType, argv: list[str]) -> int:
    """Run a command as ``pfsdm`` runs it: its declared files checked first."""
    args = _command_args(module, argv)
    check_command_files(args)
    return int(args.func(args) or 0)


def cmd_demo(args: argparse.Namespace) -> int:
    """Run ``pfsdm demo``: the reports, then the time-lapse measured, traced and compared."""
    import pandas as pd

    from ..io import check_outputs, save_tiff, write_table

    out = Path(args.output)
    if (out.exists() or out.is_symlink()) and not out.is_dir():
        raise UserError(f"the demo's output folder {out} is a file; give a folder name")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create the folder {out}: {exc.strerror}") from exc
    # every file the demo writes, checked before any work: a file of the same name that pfsdm
    # did not write (a user's groups.csv) is never replaced without --force
    check_outputs(demo_outputs(out, not args.quick_only), force=args.force)
    failed = [] if args.quick_only else _run_examples(out)

    say("== synthetic gastruloid time-lapse: measure, trajectories, distances ==")
    try:
        from ..data.gastruloids import make_timelapse_montage
    except ImportError as exc:
        raise UserError(f"the bundled synthetic data is not available ({exc})") from exc
    labels, intensity, groups = make_timelapse_montage(seed=0)
    save_tiff(out / "montage_labels.tif", labels, compression="zlib")
    save_tiff(out / "montage_intensity.tif", intensity, compression="zlib")
    write_table(pd.DataFrame({"label": list(groups), "group": list(groups.values())}),
                    out / "groups.csv", {}, table_type="groups")
    say(f"   wrote {out / 'montage_labels.tif'}, {out / 'montage_intensity.tif'} "
         f"({labels.shape[0]} frames, {len(groups)} objects) and {out / 'groups.csv'}")
    common = (["--quiet"] if args.quiet else []) + (["--force"] if args.force else [])
    # what 'pfsdm measure montage_labels.tif --intensity montage_intensity.tif' does, with a
    # bar that counts objects as their frames are measured (every frame holds all objects)
    from ..batch.movies import Movie
    from ..batch.run import run_batch

    n_frames, per_frame = int(labels.shape[0]), len(groups)
    say(f"measuring {out / 'montage_labels.tif'} with its reporter -> {out / 'features.csv'}",
         args.quiet)
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(total=n_frames * per_frame, desc="measuring", unit="object",
                   file=sys.stderr, dynamic_ncols=True)

    def objects_done(stage: str, done: int, total: int, what: str) -> None:
        if bar is not None and stage == "measuring":
            bar.update(done * per_frame - bar.n)
            if done >= total:
                bar.close()  # before the messages about the finished movie

    t0 = time.perf_counter()
    try:
        table = run_batch([Movie("montage", out / "montage_labels.tif",
                                 out / "montage_intensity.tif")], out / "features.csv",
                          scheduler=args.scheduler, frames_per_task=2, progress=objects_done,
                          log=lambda m: say("  " + m, args.quiet), link="auto")
    finally:
        if bar is not None:
            bar.close()
    say(f"wrote {out / 'features.csv'} (options in features.csv.json): {len(table)} objects "
         f"in {time.perf_counter() - t0:.1f} s", args.quiet)
    last = n_frames - 1
    rc = _run_command(trajectories, [
        "trajectories", str(out / "features.csv"), "-o", str(out / "pca.csv"),
        "--plot", str(out / "pca.png"), "--groups", str(out / "groups.csv"), *common])
    rc = rc or _run_command(compare, [
        "compare", str(out / "features.csv"), "-o", str(out / "distances.csv"),
        "--frames", str(last), "--groups", str(out / "groups.csv"),
        "--intensity-weight", "0.5", *common])
    if rc:
        return rc
    # the map of the last frame, titled with what it shows
    from ..analysis.features import drop_failed
    from ..analysis.groups import attach_groups, read_groups
    from ..analysis.reduction import mds_coordinates
    from ..analysis.tables import distance_matrix
    from ..batch.reports import load_features, plot_mds

    table = load_features(out / "features.csv")
    shown = attach_groups(drop_failed(table[table["frame"] == last]).reset_index(drop=True),
                          read_groups(out / "groups.csv"))
    plot_mds(mds_coordinates(distance_matrix(shown, intensity_weight=0.5)), shown,
             out / "mds.png",
             title=f"PF-SDM distances (shape + 0.5 × intensity), 2-D MDS\n"
                   f"frame {last} (the last) of the time-lapse, {len(shown)} objects")
    say(f"wrote {out / 'mds.png'} (classical MDS of frame {last}'s distances)", args.quiet)
    files = sorted(p.name for p in out.iterdir() if p.is_file())
    say(f"demo done: {out} holds {', '.join(files)}")
    if failed:
        print(f"pfsdm: error: demo parts failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``pfsdm demo`` to ``sub`` (the subcommands of
    :func:`~napari_pfsdm.cli.build_parser`, or the demo's own), ``cmd_*`` as its ``func``."""
    fmt = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(
        "demo", formatter_class=fmt,
        help="run everything on bundled synthetic data (no display needed)",
        description="""\
Run the whole analysis on bundled synthetic data and write tables and plots into a folder:
the five-shape benchmark, the gastruloid axis-number report, and a synthetic gastruloid
time-lapse measured from TIFF files -> features.csv, pca.csv/pca.png, distances.csv/mds.png.
""")
    file_argument(p, "-o", "--output", role="output", kind="folder", default="results",
                  metavar="DIR", help="output folder (default: results); a file there that "
                                      "pfsdm did not write is never replaced (without --force)")
    p.add_argument("--scheduler", default="processes", metavar="WHERE",
                   help="as for 'pfsdm measure' (default processes)")
    p.add_argument("--quick-only", action="store_true",
                   help="skip the two benchmark reports; only the time-lapse part")
    add_force(p)
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_demo)
