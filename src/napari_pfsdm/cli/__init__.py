"""The ``pfsdm`` command line: measure movies, compare shapes, plot trajectories, classify.

Run ``pfsdm --help`` or ``pfsdm COMMAND --help``. Every command runs without a display.
Errors a user can fix (a missing file, labels and intensity of different sizes, a raw image
given as labels, an output folder that cannot be written, an output name that would replace a
file pfsdm did not write) print one line starting with ``pfsdm: error:`` and exit with status
2, without a traceback (``--debug`` shows it); no partial output file is left behind. Those are
the :class:`~napari_pfsdm.errors.InputError` raised where the input is wrong (and its
subclass :class:`~napari_pfsdm.errors.RunFault`: a worker killed, a cluster lost), plus the
file system's ``OSError`` and a missing optional package; any other exception is a bug of
napari-pfsdm: pfsdm says so, where to report it, and exits with status 1. Tables are
plain CSV with their options in a ``.csv.json`` sidecar (Parquet for a ``.parquet`` name).
Messages and progress go to stderr
(``-q`` silences them); results and summaries to stdout.

Here: the parser (:func:`build_parser`) and :func:`main`, which turns errors into exit
statuses. Each command is a module of this package that declares its own subparser
(``add_parser``) beside its ``cmd_*`` function: :mod:`.measure`, :mod:`.compare`,
:mod:`.trajectories`, :mod:`.classify` (classify and predict), :mod:`.stats`, :mod:`.plot`,
:mod:`.report`, :mod:`.demo`; what they share is in :mod:`.common` (messages, errors, output
checks, option types) and :mod:`.tables` (a table as the commands read it).
"""

from __future__ import annotations

import argparse
import sys
import traceback
from collections.abc import Sequence

from ..errors import InputError
from . import classify, compare, demo, measure, plot, report, stats, trajectories
from .common import BUG_REPORT, EXIT_BUG, EXIT_USAGE, check_command_files

__all__ = ["build_parser", "main"]

#: The commands in the order ``pfsdm --help`` lists them; each module adds its own parser.
COMMANDS = (measure, compare, trajectories, classify, stats, plot, report, demo)

DESCRIPTION = """\
PF-SDM shape analysis of segmented objects, from the command line.

Typical session (a folder of label movies, one TIFF or Zarr per movie):

  pfsdm measure movies/ -o features.csv               one row per movie, frame and object
  pfsdm trajectories features.csv -o pca.csv --plot pca.png --groups groups.csv
  pfsdm compare features.csv --frames 0 -o distances.csv --mds mds.png
  pfsdm classify features.csv --groups groups.csv --frames 0-10
  pfsdm report features.csv -o report.html --groups groups.csv --labels labels.tif
  pfsdm demo -o results/                               all of it on bundled synthetic data

A groups.csv has a 'group' column and 'label' and/or 'movie' columns, e.g.
  movie,group
  gastruloid01,single-axis
"""


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser of ``pfsdm`` (used by :func:`main` and for the docs)."""
    from .._version import __version__

    fmt = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(prog="pfsdm", description=DESCRIPTION, formatter_class=fmt)
    parser.add_argument("--version", action="version", version=f"pfsdm {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the full Python traceback on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``pfsdm`` with ``argv`` (default: the command line); return the exit status.

    0 on success; 2 for an error the user can fix (one plain ``pfsdm: error:`` line on stderr);
    1 for a bug (it says so and where to report it; ``--debug`` prints the traceback first, in
    both cases); 130 when interrupted.
    """
    import logging

    parser = build_parser()
    args = parser.parse_args(argv)
    if not args.debug:  # tifffile logs a damaged file's details; the error line says it
        logging.getLogger("tifffile").setLevel(logging.CRITICAL)
    try:
        check_command_files(args)  # every declared output against the others and the inputs
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("pfsdm: interrupted (finished movies are kept; run again to resume)",
              file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - sorted below into the user's and ours
        if args.debug:
            traceback.print_exc(file=sys.stderr)
        if _is_input_error(exc):
            msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            if isinstance(exc, OSError) and exc.strerror:  # the system's words, and the file
                msg = f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
                from ..io.atomic import WRITE_HINTS

                hint = WRITE_HINTS.get(exc.errno or 0)
                if hint and hint not in msg:
                    msg += f"; {hint}"
            print(f"pfsdm: error: {msg}", file=sys.stderr)
            return EXIT_USAGE
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        print(f"pfsdm: internal error (a bug of napari-pfsdm, not of your input): "
              f"{type(exc).__name__}{': ' + text if text else ''}", file=sys.stderr)
        print(f"pfsdm: {BUG_REPORT}"
              + ("" if args.debug else " (--debug prints the traceback)"), file=sys.stderr)
        return EXIT_BUG


def _is_input_error(exc: BaseException) -> bool:
    """Whether ``exc`` is the user's to fix (exit 2) rather than a bug (exit 1).

    An :class:`InputError` (raised where the input is wrong), an ``OSError`` (a file that cannot
    be read or written: missing, no permission, disk full) and an ``ImportError`` of an optional
    package that is not installed. An ``ImportError`` of napari-pfsdm's own modules, and every
    other exception (a plain ``ValueError`` from numpy included), is a bug.
    """
    if isinstance(exc, InputError | OSError):
        return True
    if isinstance(exc, ImportError):
        name = getattr(exc, "name", None) or ""
        return not name.startswith("napari_pfsdm")
    return False


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
