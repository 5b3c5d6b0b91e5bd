"""What every command shares: the exit statuses and the user's errors, the messages on
stderr and stdout, the check of an output name before any work, and the options and
argument types several commands take."""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..errors import InputError

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

def _say(msg: str, quiet: bool = False) -> None:
    """A result or summary on stdout."""
    if not quiet:
        print(msg, flush=True)


def _note(msg: str, quiet: bool = False) -> None:
    """A message about the run (progress, rows left out) on stderr."""
    if not quiet:
        print(f"pfsdm: {msg}", file=sys.stderr, flush=True)


class _Step:
    """Says on stderr what a step is doing and, when it took more than a second, how long:
    every step that can pass a few seconds on a large table is announced."""

    def __init__(self, what: str, quiet: bool):
        self.what, self.quiet = what, quiet

    def __enter__(self) -> _Step:
        self.t0 = time.perf_counter()
        _note(f"{self.what} …", self.quiet)
        return self

    def __exit__(self, kind, *rest) -> None:
        dt = time.perf_counter() - self.t0
        if kind is None and dt > 1.0:
            _note(f"{self.what}: done in {dt:.1f} s", self.quiet)


# --------------------------------------------------------------------------------------------
# outputs
# --------------------------------------------------------------------------------------------

def _check_output(
    path: str | os.PathLike, what: str = "output", *, force: bool = False,
    inputs: Sequence[str | os.PathLike] = (),
) -> Path:
    """Fail early (before any long work) when ``path`` cannot or must not be written."""
    from ..io import check_overwrite

    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    if p.is_dir():
        raise UserError(f"the {what} {p} is a folder; give a file name such as {p / 'out.csv'}")
    if not folder.is_dir():
        raise UserError(f"cannot write the {what} {p}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise UserError(f"cannot write the {what} {p}: the folder {folder} is not writable")
    for q in inputs:
        if Path(q).exists() and p.exists() and os.path.samefile(p, q):
            raise UserError(f"the {what} {p} is also an input; choose another output name")
    check_overwrite(p, force=force, what=what, table=what not in ("plot", "report"))
    if p.suffix.lower() == ".parquet":  # a missing package fails now, not after the work
        from ..io import require_pyarrow

        require_pyarrow(p, "writing")
    return p


def _check_parts(parts: Path) -> None:
    """Refuse a parts folder name that is taken by something other than a folder."""
    if (parts.exists() or parts.is_symlink()) and not parts.is_dir():
        raise UserError(
            f"{parts} already exists and is not a folder, but pfsdm keeps the finished movies' "
            "parts in a folder of that name; nothing was changed. Move that file, or give "
            "another folder with --parts")


# --------------------------------------------------------------------------------------------
# options and their types
# --------------------------------------------------------------------------------------------

def _option_type(opt: Any) -> Callable[[str], Any]:
    """argparse's ``type`` of a method option: the text parsed and checked by the record, so
    that a bad value gets the same words as from Python (``Option.message``)."""
    def parse(text: str) -> Any:
        try:
            return opt.parse(text)
        except InputError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = opt.name
    return parse


def _whole(flag: str, low: int) -> Callable[[str], int]:
    """argparse's ``type`` of a count: a whole number of at least ``low``, else one line
    saying so (``--workers 0`` was once taken as the default without a word)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low:
            raise argparse.ArgumentTypeError(
                f"{flag} must be a whole number of at least {low}; got {text!r}")
        return value

    parse.__name__ = flag.lstrip("-")
    return parse


def _fraction(flag: str) -> Callable[[str], float]:
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


def _add_groups_link_force_quiet(p: argparse.ArgumentParser) -> None:
    """``--groups``, ``--link``, ``--force`` and ``-q`` as the table-reading commands take them."""
    p.add_argument("--groups", metavar="GROUPS.csv",
                   help="CSV with a 'group' column and 'label', 'track_id' and/or 'movie'")
    p.add_argument("--link", choices=("centroid", "laptrack", "none"),
                   help="as for 'pfsdm trajectories'")
    _add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")


def _add_elastic(p: argparse.ArgumentParser, more: str) -> None:
    """``--elastic [W]``: the elastic outline term in the distance (``elastic_weight``; the
    recommended weight when given alone); ``more``: what it changes in this command."""
    from ..core.distances import RECOMMENDED_ELASTIC_WEIGHT
    from ..core.params import option

    elastic = option("elastic_weight")
    p.add_argument("--elastic", nargs="?", dest="elastic_weight", type=_option_type(elastic),
                   const=RECOMMENDED_ELASTIC_WEIGHT, default=elastic.default, metavar="W",
                   help="add the elastic outline term, weight W (default when given "
                        f"{RECOMMENDED_ELASTIC_WEIGHT:g}, the weight that retrieves best): "
                        "for articulated or detailed outlines and retrieval; not for round "
                        "nuclei or clustering silhouettes (docs/method.md). Needs a table "
                        f"measured with --elastic-signature table; about 3x the time; {more}")


def _check_elastic(table, args: argparse.Namespace) -> None:
    """``--elastic`` needs the outline signatures in the table: say how to measure them."""
    from ..core.table_schema import has_signature

    if args.elastic_weight and not has_signature(table.columns)[0]:
        raise UserError(
            f"--elastic compares the objects' outline signatures, and {args.features} has "
            "none (no elastic_* columns): measure the movies again with "
            "'pfsdm measure ... --elastic-signature table', or leave --elastic out")


def _elastic_notice(args: argparse.Namespace):
    """With ``--elastic``: numba's first compile of the term's kernels said on stderr (unless
    ``-q``); else nothing."""
    import contextlib

    if not getattr(args, "elastic_weight", 0):
        return contextlib.nullcontext()
    from ..core.compiled import compile_notice

    return compile_notice(lambda message: _note(message, args.quiet))


def _add_force(p: argparse.ArgumentParser) -> None:
    """``--force``: replace output files pfsdm did not write."""
    p.add_argument("--force", action="store_true",
                   help="replace output files even when pfsdm did not write them (by default "
                        "an existing file that is not a pfsdm table or plot is never replaced)")
