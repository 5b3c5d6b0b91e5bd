"""What every command shares: the exit statuses and the user's errors, the messages on
stderr and stdout, the check of an output name before any work, and the options and
argument types several commands take."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.params import LINK_OPTION
from ..errors import InputError

#: The identities (the option ``link``) a command that reads a table offers: all but
#: ``overlap``, which needs the label images.
TABLE_LINKS = tuple(c for c in LINK_OPTION.choices if c != "overlap")

#: The exit status of an error the user can fix, and of a bug.
EXIT_USAGE = 2
EXIT_BUG = 1


#: An error the user can fix; printed as one line (the one class: errors.InputError).
UserError = InputError

#: Where a bug is reported: the README's wording ("Reporting a problem"); a test holds them equal.
BUG_REPORT = ("please report it on the issue tracker of the napari-pfsdm repository (its "
              "Issues page), with the command and the output of the same command run with "
              "--debug")


# --------------------------------------------------------------------------------------------
# messages
# --------------------------------------------------------------------------------------------

def say(msg: str, quiet: bool = False) -> None:
    """A result or summary on stdout."""
    if not quiet:
        print(msg, flush=True)


def note(msg: str, quiet: bool = False) -> None:
    """A message about the run (progress, rows left out) on stderr."""
    if not quiet:
        print(f"pfsdm: {msg}", file=sys.stderr, flush=True)


class Step:
    """Says on stderr what a step is doing and, when it took more than a second, how long:
    every step that can pass a few seconds on a large table is announced."""

    def __init__(self, what: str, quiet: bool):
        self.what, self.quiet = what, quiet

    def __enter__(self) -> Step:
        self.t0 = time.perf_counter()
        note(f"{self.what} …", self.quiet)
        return self

    def __exit__(self, kind, *rest) -> None:
        dt = time.perf_counter() - self.t0
        if kind is None and dt > 1.0:
            note(f"{self.what}: done in {dt:.1f} s", self.quiet)


# --------------------------------------------------------------------------------------------
# outputs
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FileArgument:
    """An argument of a command that names a file it writes (``role="output"``) or reads
    (``"input"``): ``kind`` as :class:`napari_pfsdm.io.outputs.Output` and ``Input`` take it,
    ``name`` the option as the user types it (``-o``, ``--plot``) or what a positional is."""

    dest: str
    role: str
    kind: str
    name: str


def file_argument(p: argparse.ArgumentParser, *flags: str, role: str, kind: str,
                  name: str | None = None, **kw: Any) -> argparse.Action:
    """Add an argument that names a file the command writes or reads, and declare it: every
    command's declared files are checked before it runs (:func:`check_command_files`), so
    that a new command gets the checks by declaring its files this way."""
    if role not in ("output", "input"):
        raise ValueError(f"role must be 'output' or 'input', not {role!r}")
    action = p.add_argument(*flags, **kw)
    files = p.get_default("pfsdm_files")
    if files is None:
        files = []
        p.set_defaults(pfsdm_files=files)
    shown = name or (action.option_strings[0] if action.option_strings else action.dest)
    files.append(FileArgument(action.dest, role, kind, shown))
    return action


def declared_files(args: argparse.Namespace) -> tuple[list, list]:
    """The outputs and inputs a command's arguments name (:func:`file_argument`), as
    :class:`napari_pfsdm.io.outputs.Output` and ``Input``, with the outputs it derives from
    them (``pfsdm_derived``, e.g. the default parts folder of ``pfsdm measure``); movie
    inputs given as folders or globs are the movies found there."""
    from ..io.outputs import Input, Output

    outputs, inputs = [], []
    for f in getattr(args, "pfsdm_files", None) or []:
        value = getattr(args, f.dest, None)
        values = value if isinstance(value, list | tuple) else [value]
        for v in values:
            if v is None or str(v) == "":
                continue
            if f.role == "output":
                outputs.append(Output(Path(v), f.kind, f.name))
            else:
                inputs += [Input(p, f.kind, f.name) for p in _input_paths(str(v), f.kind)]
    derived = getattr(args, "pfsdm_derived", None)  # files a command derives from others
    if derived is not None:
        outputs += derived(args)
    return outputs, inputs


def _input_paths(text: str, kind: str) -> list[Path]:
    """The files an input argument names: a movie folder or glob is the movies found there
    (an error there is the command's to say, in its own words)."""
    if kind != "movie":
        return [Path(text)]
    from ..batch.movies import find_movies

    try:
        return list(find_movies(text))
    except (InputError, OSError):
        return [Path(text)]


def check_command_files(args: argparse.Namespace) -> None:
    """Before a command runs: its declared outputs can be written, replace no file pfsdm did
    not write (without ``--force``), and are neither each other nor one of its inputs
    (:func:`napari_pfsdm.io.outputs.check_outputs`)."""
    from ..io.outputs import check_outputs

    outputs, inputs = declared_files(args)
    check_outputs(outputs, inputs, force=bool(getattr(args, "force", False)))


def check_parts(parts: Path) -> None:
    """Refuse a parts folder name that is taken by something other than a folder."""
    if (parts.exists() or parts.is_symlink()) and not parts.is_dir():
        raise UserError(
            f"{parts} already exists and is not a folder, but pfsdm keeps the finished movies' "
            "parts in a folder of that name; nothing was changed. Move that file, or give "
            "another folder with --parts")


# --------------------------------------------------------------------------------------------
# options and their types
# --------------------------------------------------------------------------------------------

def option_type(opt: Any) -> Callable[[str], Any]:
    """argparse's ``type`` of a method option: the text parsed and checked by the record, so
    that a bad value gets the same words as from Python (``Option.message``)."""
    def parse(text: str) -> Any:
        try:
            return opt.parse(text)
        except InputError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = opt.name
    return parse


def whole_number(flag: str, low: int, high: int | None = None,
           why: str = "") -> Callable[[str], int]:
    """argparse's ``type`` of a count: a whole number from ``low`` to ``high`` (no upper bound
    when None), else one line saying so (``--workers 0`` was once taken as the default
    without a word); ``why`` says what the upper bound is."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low or (high is not None and value > high):
            span = f"of at least {low}" if high is None else f"from {low} to {high:,}"
            raise argparse.ArgumentTypeError(
                f"{flag} must be a whole number {span}{why}; got {text!r}")
        return value

    parse.__name__ = flag.lstrip("-")
    return parse


def seed_number(text: str) -> int:
    """argparse's ``type`` of ``--seed``: a whole number from 0 to
    :data:`napari_pfsdm.analysis.prediction.MAX_SEED` (scikit-learn's range, less the seeds
    the splits add to it)."""
    from ..analysis.prediction import check_seed

    try:
        value: Any = int(text)
    except ValueError:
        value = text
    try:
        return check_seed(value, "--seed")
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def worker_count(flag: str = "--workers") -> Callable[[str], int]:
    """argparse's ``type`` of a number of local workers: at least 1, at most the cores this
    process may use (:func:`napari_pfsdm.analysis.schedulers.check_workers`)."""
    from ..analysis.schedulers import check_workers

    count = whole_number(flag, 1)

    def parse(text: str) -> int:
        value = count(text)
        try:
            return int(check_workers(value, flag))
        except InputError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = flag.lstrip("-")
    return parse


def real_number(flag: str, low: float, high: float) -> Callable[[str], float]:
    """argparse's ``type`` of a finite number from ``low`` to ``high``."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not low <= value <= high:  # NaN fails too
            raise argparse.ArgumentTypeError(
                f"{flag} must be a number from {low:g} to {high:g}; got {text!r}")
        return value

    parse.__name__ = flag.lstrip("-")
    return parse


def fraction_number(flag: str) -> Callable[[str], float]:
    """argparse's ``type`` of a fraction strictly between 0 and 1."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not 0.0 < value < 1.0:
            raise argparse.ArgumentTypeError(
                f"{flag} must be a number strictly between 0 and 1; got {text!r}")
        return value

    parse.__name__ = flag.lstrip("-")
    return parse


def add_groups(p: argparse.ArgumentParser, required: bool = False, use: str = "") -> None:
    """``--groups`` and ``--group-column``, as every command that reads groups takes them."""
    file_argument(p, "--groups", role="input", kind="file", metavar="GROUPS.csv",
                  required=required,
                  help="CSV of the objects' groups as the lab keeps it: a 'movie' column "
                       "(names with or without folder and extension), and/or 'label' or "
                       "'track_id', and grouping columns (group, clone, genotype, …)"
                       + (f"; {use}" if use else ""))
    p.add_argument("--group-column", metavar="COLUMN",
                   help="the groups file's column to group by (default: 'group', or its only "
                        "grouping column); its other columns are kept in the outputs")


def selected_frames(text: str, table) -> list[int]:
    """``--frames`` read against the table's frames: ranges are never listed frame by frame,
    and frames the table does not have are refused, naming them
    (:func:`napari_pfsdm.analysis.classification.parse_frames`)."""
    from ..analysis.classification import parse_frames

    try:
        return parse_frames(text, available=table["frame"])
    except InputError as exc:
        raise UserError(f"--frames {text}: {exc}") from None


def add_groups_link_force_quiet(p: argparse.ArgumentParser) -> None:
    """``--groups``, ``--link``, ``--force`` and ``-q`` as the table-reading commands take them."""
    add_groups(p)
    p.add_argument("--link", choices=TABLE_LINKS, help="as for 'pfsdm trajectories'")
    add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")


def add_elastic(p: argparse.ArgumentParser, more: str) -> None:
    """``--elastic [W]``: the elastic outline term in the distance (``elastic_weight``; the
    recommended weight when given alone); ``more``: what it changes in this command."""
    from ..core.distances import RECOMMENDED_ELASTIC_WEIGHT
    from ..core.params import option

    elastic = option("elastic_weight")
    p.add_argument("--elastic", nargs="?", dest="elastic_weight", type=option_type(elastic),
                   const=RECOMMENDED_ELASTIC_WEIGHT, default=elastic.default, metavar="W",
                   help="add the elastic outline term, weight W (default when given "
                        f"{RECOMMENDED_ELASTIC_WEIGHT:g}, the weight that retrieves best): "
                        "for articulated or detailed outlines and retrieval; not for round "
                        "nuclei or clustering silhouettes (docs/method.md). Needs a table "
                        f"measured with --elastic-signature table; about 3x the time; {more}")


def check_elastic(table, args: argparse.Namespace) -> None:
    """``--elastic`` needs the outline signatures in the table: say how to measure them."""
    from ..core.table_schema import has_signature

    if args.elastic_weight and not has_signature(table.columns)[0]:
        raise UserError(
            f"--elastic compares the objects' outline signatures, and {args.features} has "
            "none (no elastic_* columns): measure the movies again with "
            "'pfsdm measure ... --elastic-signature table', or leave --elastic out")


def elastic_notice(args: argparse.Namespace):
    """With ``--elastic``: numba's first compile of the term's kernels said on stderr (unless
    ``-q``); else nothing."""
    import contextlib

    if not getattr(args, "elastic_weight", 0):
        return contextlib.nullcontext()
    from ..core.compiled import compile_notice

    return compile_notice(lambda message: note(message, args.quiet))


def add_force(p: argparse.ArgumentParser) -> None:
    """``--force``: replace output files pfsdm did not write."""
    p.add_argument("--force", action="store_true",
                   help="replace output files even when pfsdm did not write them (by default "
                        "an existing file that is not a pfsdm table or plot is never replaced)")
