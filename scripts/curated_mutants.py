#!/usr/bin/env python3
"""The curated mutants: one-line bugs that once happened or that a reviewer planted, each run
against the tests that should catch it.

    python scripts/curated_mutants.py                           # all, against the non-GUI suite
    python scripts/curated_mutants.py --list                    # the mutants, nothing run
    python scripts/curated_mutants.py --modules analysis/tracking.py \
        --tests tests/test_tracking.py tests/test_linking_gates.py   # one module, its tests
    python scripts/curated_mutants.py --report curated.json     # keep the verdicts
    python scripts/curated_mutants.py --again curated.json      # only its survivors again

The broad sweep of generated mutants (every operator, constant and string of a module) is
mutmut's job, configured in pyproject.toml (``[tool.mutmut]``; docs/testing.md). What mutmut
cannot plant are the bugs of :data:`CURATED`: a named line changed as someone did change it
(a linking gate dropped, a sign in the per-object diagnostics, a word in the explanations, a
table check forgetting a channel's columns, a fault guard undone). Each is named by its text
and, when the text recurs, its function; a text found on no line or on several stops the run.

How it runs (one job at a time: the machine has 2 cores):

1. The repository is copied to a temporary folder (the work tree is never changed) and the
   tests run there with ``PYTHONPATH`` pointing at the copy's ``src``.
2. The non-GUI suite (or the files ``--tests`` names) runs once with a profiler hook that
   records which package functions each test calls; a mutant then runs only the tests that
   call the function it is in (``-x``: the first failure kills it), fastest first.
3. A mutant is *killed* when those tests fail or error (or exceed ``--timeout``), *survived*
   when they pass, *not covered* when no test calls its function (counted as survived).

Use the same interpreter as the tests (``.venv/bin/python scripts/curated_mutants.py``).
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = Path("src/napari_pfsdm")


@dataclass
class Mutant:
    """One one-line change: in ``path`` (under src/napari_pfsdm), line ``line`` becomes
    ``new`` (was ``old``)."""

    path: str
    line: int
    kind: str
    old: str
    new: str
    function: str = ""
    first_line: int = 0  # of the enclosing function (0: module level)
    curated: str = ""
    verdict: str = ""
    seconds: float = 0.0
    tests: list[str] = field(default_factory=list)

    @property
    def ident(self) -> str:
        return f"{self.path}:{self.line}:{self.kind}"


#: Curated mutants, as (path, exact old text, new text, what it is[, function]): the kinds of
#: one-line bugs that once survived the suite or that a reviewer planted. The old text must
#: occur on exactly one line of the module, or of the named function (its qualified name,
#: e.g. ``"cmd_compare"``) when the text recurs; a mismatch (the line was edited, or the
#: text became ambiguous) stops the run with a message rather than being skipped silently.
CURATED = [
    ("core/morphometric.py", "w = w / (1.0 - r) ** 2", "w = w / (1.0 - r)",
     "depth ring weight without its square"),
    ("core/descriptor3d.py", "sh_analysis(radius / scale - 1.0, grid)",
     "sh_analysis(radius / scale, grid)", "3-D surface term without the -1"),
    ("analysis/tracking.py", "for back in range(2, max_gap + 2):  # gap closing over missed",
     "for back in range(2, max_gap + 1):  # gap closing over missed",
     "centroid gap closing one frame short"),
    ("analysis/shape_space.py", "ratio = self.pca_.explained_variance_ratio_",
     "ratio = self.pca_.explained_variance_ / self.pca_.explained_variance_.sum()",
     "explained variance divided by the kept components' variance"),
    ("analysis/rerank.py", "sigma = np.take_along_axis(off, order[:, -1:], axis=1)[:, 0]",
     "sigma = np.take_along_axis(off, order[:, :1], axis=1)[:, 0]",
     "local scale from the 1st instead of the k-th neighbour"),
    ("io/tables.py", 'TEXT_COLUMNS = ("movie", "group", "error", "warnings")',
     'TEXT_COLUMNS = ("group", "error", "warnings")', '"001" movie names read as numbers'),
    ("cli/compare.py", "boundary_weight=args.boundary_weight)",
     "boundary_weight=None)", "compare --boundary-weight ignored", "cmd_compare"),
    # what issue 43 added: each guard undone (tests/test_faults.py must kill them)
    ("core/intensity.py", "bad = ~np.isfinite(values)", "bad = np.isnan(values)",
     "+inf reporter pixels inside an object accepted"),
    ("batch/io.py", "if arr.metadata.encode_chunk_key(coords) not in present:",
     "if False:", "missing Zarr chunks never found"),
    ("batch/fingerprint.py", "if sum(size for size, _ in files.values()) <= CONTENT_HASH_BYTES:",
     "if False:", "small movies fingerprinted by size and time only"),
    ("io/sidecar.py", 'and hashlib.sha256(data).hexdigest() == side["table_sha256"]):',
     "or True):", "a table paired with any sidecar"),
    ("io/sidecar.py", "if not strict and changed_after(path):", "if changed_after(path):",
     "a damaged part taken for an edit"),
    ("batch/tasks.py", "if isinstance(exc, BrokenExecutor):", "if False:",
     "a killed worker reported as a bug"),
    ("batch/run.py", "empty[m.name] = _empty_frames(table, lab, axes)", "empty[m.name] = []",
     "frames without objects not named"),
    # issue 43 point 10: the four sorts of one-line bugs a reviewer planted, across analysis/
    # and core/. (1) a gate dropped or flipped in the default linking and its checks
    ("analysis/tracking.py", "for i, j in zip(r, c, strict=True) if d[i, j] <= dist]",
     "for i, j in zip(r, c, strict=True)]", "centroid links kept beyond the distance gate"),
    ("analysis/tracking.py", "r, c = linear_sum_assignment(np.where(d <= dist, d, 1e12))",
     "r, c = linear_sum_assignment(d)", "centroid assignment blind to the distance gate",
     "link_centroids.nearest"),
    ("analysis/tracking.py", " for i in prev if tr[i] not in continued})", " for i in prev})",
     "continued tracks offered to gap closing"),
    ("analysis/tracking.py", "free = cur[tr[cur] == NO_TRACK]", "free = cur",
     "gap closing re-links objects already linked"),
    ("analysis/tracking.py", "else LINK_RADII * _median_radius(table))",
     "else _median_radius(table))", "default link distance one radius, not LINK_RADII"),
    ("analysis/tracking.py", "return float(np.sqrt(np.median(area) / np.pi)) if len(area) else",
     "return float(np.sqrt(np.median(area))) if len(area) else",
     "median radius without the 1/π"),
    ("analysis/tracking.py", "area = area[np.isfinite(area) & (area > 0)]",
     "area = area[np.isfinite(area) | (area > 0)]", "NaN areas in the median radius"),
    ("analysis/tracking.py", "if persistence < MIN_PERSISTENCE:", "if False:",
     "the persistence gate of check_tracking dropped"),
    ("analysis/tracking.py", "if switched > MAX_SWITCHED:", "if switched < MAX_SWITCHED:",
     "the switch gate of check_tracking flipped"),
    ("analysis/tracking.py", "switched[steps] = rows[nearest] != here[steps]",
     "switched[steps] = rows[nearest] == here[steps]",
     "a label that stays on its object counted as switched"),
    ("analysis/tracking.py", "has_next = np.isin(frame, frames[np.isin(frames + 1, frames)])",
     "has_next = np.isin(frame, frames)", "the last frame's ids expected to persist"),
    ("analysis/tracking.py", "radius = np.sqrt(0.5 * (area[here] + area[there]) / np.pi)",
     "radius = np.sqrt((area[here] + area[there]) / np.pi)",
     "jump radius from the summed, not the mean, area"),
    ("analysis/tracking.py", "if gain[rows[i], cols[j]] >= min_iou]", "]",
     "overlap pairs below min_iou linked"),
    ("analysis/tracking.py", "if i not in matched_prev:", "if True:",
     "overlap: matched objects offered to gap closing"),
    ("analysis/tracking.py", "iou[:, ~free] = 0", "pass",
     "overlap gap closing re-links objects already linked"),
    ("analysis/tracking.py", "keep = ids > 0", "keep = ids >= 0", "background taken for an object"),
    ("analysis/tracking.py", "if out[row] != NO_TRACK or key in taken:",
     "if out[row] != NO_TRACK and key in taken:", "two rows given one Tracks point"),
    # (2) a sign or a comparison in the per-object diagnostics and their warnings
    ("core/descriptor.py", "folded = disk > 0", "folded = disk < 0",
     "folded samples: the inside counted instead of the outside"),
    ("core/descriptor.py", "folded |= jacobian <= 0", "folded |= jacobian < -1",
     "a vanishing Jacobian not counted as a fold"),
    ("core/descriptor3d.py", "float(((ball > 0) * solid[None]).sum() / len(r))",
     "float(((ball < 0) * solid[None]).sum() / len(r))",
     "3-D folded samples: the inside counted"),
    ("core/descriptor3d.py", "\"crossing_fraction\": float((solid * (crossings > 1)).sum()),",
     "\"crossing_fraction\": float((solid * (crossings >= 1)).sum()),",
     "every ray counted as crossing more than once"),
    ("analysis/features.py", "np.isfinite(folded) and folded > FOLDED_WARNING:",
     "np.isfinite(folded) and folded < FOLDED_WARNING:",
     "folding warning for the objects that do not fold"),
    ("analysis/features.py", "if \"crossing_fraction\" in diag:",
     "if \"crossing_fraction\" not in diag:", "2-D folding called ball samples"),
    ("analysis/features.py", "if n_comp > 1:", "if n_comp >= 1:",
     "every object said to be in pieces"),
    ("analysis/features.py", "if with_intensity and obj.intensity_error:",
     "if obj.intensity_error:", "intensity warning without an intensity channel"),
    ("analysis/features.py", "if obj.touches_border:", "if not obj.touches_border:",
     "border warning for inner objects"),
    ("analysis/features.py", "over = folded[folded > FOLDED_WARNING]",
     "over = folded[folded >= 0]", "summary: every object counted as folded"),
    ("analysis/features.py", "holes = int((numbers(\"n_holes\", 0.0) > 0).sum())",
     "holes = int((numbers(\"n_holes\", 0.0) >= 0).sum())",
     "summary: every object said to have holes"),
    ("analysis/features.py", "pieces = int((numbers(\"n_components\", 1.0) > 1).sum())",
     "pieces = int((numbers(\"n_components\", 1.0) >= 1).sum())",
     "summary: every object said to be in pieces"),
    ("analysis/features.py", "errors = len(texts(\"error\"))",
     "errors = len(table) - len(texts(\"error\"))",
     "summary: the measured objects counted as failed"),
    ("core/intensity.py", "if not mean > 0:", "if mean < 0:",
     "a zero mean reporter accepted"),
    ("core/intensity.py", "return np.where(np.isfinite(crop), crop / mean, 0.0)",
     "return crop / mean", "non-finite pixels around an object kept"),
    # (3) a word in the generated explanations
    ("analysis/interpretation.py", "side = \"right\" if r > 0 else \"left\"",
     "side = \"left\" if r > 0 else \"right\"", "explanation: sides swapped"),
    ("analysis/interpretation.py", "(\"minor/major axis ratio\", \"less elongated\")",
     "(\"minor/major axis ratio\", \"more elongated\")",
     "explanation: more elongated for a higher minor/major ratio"),
    ("analysis/interpretation.py", "\"circularity\": (\"circularity (4πA/P²)\", \"rounder\"),",
     "\"circularity\": (\"circularity (4πA/P²)\", \"less round\"),",
     "explanation: less round for a higher circularity"),
    ("analysis/interpretation.py", "(\"solidity (area / convex hull)\", \"less indented\")",
     "(\"solidity (area / convex hull)\", \"more indented\")",
     "explanation: more indented for a higher solidity"),
    ("analysis/interpretation.py", "if abs(r) >= threshold:", "if r >= threshold:",
     "explanation: a negative correlation called none"),
    ("analysis/interpretation.py", "best = row.abs().idxmax()", "best = row.idxmax()",
     "explanation: the most positive, not the strongest, measure"),
    ("analysis/interpretation.py", "out = np.where((n > 2) & varies(left) & varies(right),",
     "out = np.where((n > 3) & varies(left) & varies(right),",
     "correlation refused for three objects"),
    ("analysis/interpretation.py", "np.divide(minor, major, out=ratio, where=major > 0)",
     "np.divide(major, minor, out=ratio, where=major > 0)", "aspect ratio upside down"),
    ("analysis/interpretation.py", "float(np.sqrt(max(lam[0], 0.0) / lam[1]))",
     "float(max(lam[0], 0.0) / lam[1])",
     "outline aspect ratio without its square root"),
    # (4) a table check that forgets a channel's columns
    ("core/table_schema.py", "for channel in channels:", "for channel in list(channels)[:1]:",
     "check_feature_table checks the first channel only", "check_feature_table"),
    ("core/table_schema.py", "        if missing:", "        if missing and channel == \"shape\":",
     "a cut intensity channel accepted", "check_feature_table"),
    ("core/table_schema.py", "feature = re.compile(rf\"{channel}_r\\d+_[nl]\\d+\")",
     "feature = re.compile(r\"shape_r\\d+_[nl]\\d+\")",
     "extra intensity columns accepted"),
    ("core/table_schema.py", "prefix = f\"{channel}_r\"", "prefix = \"shape_r\"",
     "has_channel answers for the shape whatever the channel", "has_channel"),
    ("core/table_schema.py", "cols + surface_columns(degree) if channel == \"shape\" else cols",
     "cols", "3-D shape columns without the surface term"),
    ("core/table_schema.py", "needed = (\"weights\", \"sh_degree\", \"surface_weight\") if",
     "needed = (\"weights\", \"sh_degree\") if", "3-D options without the surface weight accepted"),
    ("core/table_schema.py", "k if k and all(c in names for c in outline_columns(k)) else 0",
     "k", "cut outline columns taken for a whole outline"),
    ("core/table_schema.py", ".startswith(prefix) and str(c)[len(prefix):].isdigit()]",
     ".startswith(prefix)]", "PC columns by prefix only"),
    ("analysis/tables.py", "    for channel in channels:", "    for channel in channels[:1]:",
     "failed_rows looks at the first channel only", "failed_rows"),
    ("analysis/tables.py", "bad |= ~np.isfinite(vals).all(axis=1)",
     "bad |= ~np.isfinite(vals).any(axis=1)", "a row with some NaN features kept"),
    ("analysis/features.py", "(\"shape\", \"intensity\") if intensity else (\"shape\",))",
     "(\"shape\",))",
     "drop_failed forgets the intensity channel"),
]


# ------------------------------------------------------------------------------------------
# the curated mutants' lines
# ------------------------------------------------------------------------------------------


def _functions(tree: ast.AST) -> list[tuple[int, int, str, int]]:
    """(first line, last line, qualified name, first line) of every function; the first line
    is that of its first decorator, as the code object's ``co_firstlineno`` says."""
    out = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                name = prefix + child.name
                first = min([child.lineno] + [d.lineno for d in child.decorator_list])
                out.append((first, child.end_lineno, name, first))
                visit(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")
            else:
                visit(child, prefix)

    visit(tree, "")
    return out


def curated_mutants(only: list[str] | None = None) -> list[Mutant]:
    """The :data:`CURATED` mutants (of the modules ``only``, when given)."""
    out = []
    for rel, old, new, what, *where in CURATED:
        if only and rel not in only:
            continue
        path = ROOT / PKG / rel
        lines = path.read_text(encoding="utf-8").splitlines()
        funcs = _functions(ast.parse("\n".join(lines)))

        def enclosing(i: int, funcs=funcs):
            inner = [f for f in funcs if f[0] <= i + 1 <= f[1]]
            return max(inner, key=lambda f: f[0]) if inner else None

        hits = [i for i, ln in enumerate(lines) if old in ln]
        if where:
            hits = [i for i in hits if (enclosing(i) or (0, 0, ""))[2] == where[0]]
        if len(hits) != 1:
            place = f"{rel} ({where[0]})" if where else rel
            raise SystemExit(f"curated mutant {what!r}: {old!r} found {len(hits)} times in "
                             f"{place}; make it unambiguous (more of the line, or the "
                             "function's name) in CURATED in scripts/curated_mutants.py")
        i = hits[0]
        fn = enclosing(i)
        out.append(Mutant(rel, i + 1, "curated", lines[i].strip(),
                          lines[i].replace(old, new).strip(), function=fn[2] if fn else "",
                          first_line=fn[3] if fn else 0, curated=what))
    return out


# ------------------------------------------------------------------------------------------
# which tests call which function
# ------------------------------------------------------------------------------------------

TRACER = r'''
import json, os, sys, threading, time
import pytest

_SRC = os.path.join(os.environ.get("PFSDM_MUTATION_ROOT", ""), "src", "napari_pfsdm") + os.sep
_calls = {}
_current = ["<collect>"]

def _hook(frame, event, arg):
    if event == "call":
        f = frame.f_code.co_filename
        if f.startswith(_SRC):
            _calls.setdefault(_current[0], set()).add((f[len(_SRC):], frame.f_code.co_firstlineno))

def pytest_collection_modifyitems(config, items):
    select = os.environ.get("PFSDM_MUTATION_SELECT")
    if select:  # run only the tests that call the mutated function, in collection order
        order = {n: k for k, n in enumerate(open(select).read().split("\n"))}
        chosen = sorted((i for i in items if i.nodeid in order), key=lambda i: order[i.nodeid])
        config.hook.pytest_deselected(items=[i for i in items if i.nodeid not in order])
        items[:] = chosen

_t0 = [0.0]
_durations = {}

def pytest_runtest_setup(item):
    _current[0] = item.nodeid
    _t0[0] = time.perf_counter()

def pytest_runtest_teardown(item):
    _durations[item.nodeid] = time.perf_counter() - _t0[0]

def pytest_configure(config):
    if os.environ.get("PFSDM_MUTATION_MAP"):
        sys.setprofile(_hook)
        threading.setprofile(_hook)

def pytest_unconfigure(config):
    if os.environ.get("PFSDM_MUTATION_MAP"):
        sys.setprofile(None)
        out = {k: sorted(v) for k, v in _calls.items()}
        with open(os.environ["PFSDM_MUTATION_MAP"], "w") as fh:
            json.dump({"calls": out, "seconds": _durations}, fh)
'''


def run_pytest(work: Path, args: list[str], timeout: float, env_extra: dict | None = None
               ) -> tuple[int, float, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(work / "src"), str(work)])
    env.pop("PYTEST_ADDOPTS", None)
    env.update(env_extra or {})
    t0 = time.perf_counter()
    try:
        out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                              "-p", "no:xvfb", "-p", "_mutation_tracer", *args], cwd=work,
                             env=env,
                             capture_output=True, text=True, timeout=timeout)
        return out.returncode, time.perf_counter() - t0, out.stdout[-2000:]
    except subprocess.TimeoutExpired:
        return -1, time.perf_counter() - t0, "timeout"


#: The GUI tests (napari, Qt) are never run: the mutated modules are tested without them.
GUI_TESTS = "tests/gui"


def call_map(work: Path, timeout: float, tests: list[str] | None = None
             ) -> dict[str, list[tuple[str, int]]]:
    """Run the non-GUI suite (or the test files ``tests``) once in ``work`` with the tracer:
    test id -> [(module, first line)] of the package functions it called (fixtures it used
    included)."""
    dest = work / "_mutation_map.json"
    code, secs, tail = run_pytest(
        work, [*(tests or ["tests"]), f"--ignore={GUI_TESTS}"], timeout,
        {"PFSDM_MUTATION_ROOT": str(work), "PFSDM_MUTATION_MAP": str(dest)})
    if code != 0:
        raise SystemExit(f"the unmutated suite does not pass in the copy ({secs:.0f} s):\n"
                         f"{tail}")
    print(f"call map: the unmutated suite passes ({secs:.0f} s with the tracer)", flush=True)
    data = json.loads(dest.read_text())
    SECONDS.update(data["seconds"])
    return {k: [tuple(x) for x in v] for k, v in data["calls"].items()}


#: Seconds each test took in the traced run: a mutant's tests run fastest first, so that the
#: first failure (``-x``) comes soon.
SECONDS: dict[str, float] = {}


def tests_for(m: Mutant, calls: dict) -> list[str]:
    """Tests that call the mutant's function (module-level code: that touch its module)."""
    if m.first_line:
        hit = [t for t, fs in calls.items() if (m.path, m.first_line) in fs]
    else:
        hit = [t for t, fs in calls.items() if any(f == m.path for f, _ in fs)]
    return sorted((t for t in hit if t.startswith("tests/") and not t.startswith(GUI_TESTS)),
                  key=lambda t: (SECONDS.get(t, 1e9), t))


# ------------------------------------------------------------------------------------------
# running
# ------------------------------------------------------------------------------------------

def copy_repo() -> Path:
    work = Path(tempfile.mkdtemp(prefix="pfsdm-mutation-"))
    ignore = shutil.ignore_patterns(".git", ".venv*", "__pycache__", "*.egg-info",
                                    ".pytest_cache", "results*", ".ruff_cache", "*.pyc")
    for name in ("src", "tests", "docs", "scripts", "benchmarks", "examples"):
        if (ROOT / name).exists():
            shutil.copytree(ROOT / name, work / name, ignore=ignore)
    for name in ("pyproject.toml", "README.md", "napari.yaml"):
        if (ROOT / name).exists():
            shutil.copy2(ROOT / name, work / name)
    return work


def apply(work: Path, m: Mutant) -> str:
    """Write the mutant into the copy; return the original text to restore."""
    path = work / PKG / m.path
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    old = lines[m.line - 1]
    indent = old[: len(old) - len(old.lstrip())]
    lines[m.line - 1] = indent + m.new + ("\n" if old.endswith("\n") else "")
    path.write_text("".join(lines), encoding="utf-8")
    return text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--modules", nargs="*",
                    help="only the mutants of these (e.g. analysis/tracking.py io/sidecar.py)")
    ap.add_argument("--timeout", type=float, default=300,
                    help="seconds per mutant before it counts as killed (default 300)")
    ap.add_argument("--tests", nargs="*", metavar="FILE",
                    help="trace and run only these test files (default: the non-GUI suite, "
                         "tests/ without tests/gui)")
    ap.add_argument("--list", action="store_true", help="list the mutants and stop")
    ap.add_argument("--report", type=Path, help="write the results as JSON here")
    ap.add_argument("--again", type=Path, metavar="REPORT",
                    help="run only the survivors of an earlier --report again (found by "
                         "their line's text: after the tests that should kill them)")
    args = ap.parse_args(argv)

    if args.again:
        chosen = survivors_of(args.again)
        print(f"{len(chosen)} survivors of {args.again} again", flush=True)
        return run(chosen, args)
    chosen = curated_mutants(args.modules)
    print(f"{len(chosen)} curated mutants", flush=True)
    if args.list:
        for m in chosen:
            print(f"{m.ident:45s} {m.old}\n{'':45s} {m.new}\n{'':45s} ({m.curated})")
        return 0
    return run(chosen, args)


def survivors_of(report: Path) -> list[Mutant]:
    """The survivors of an earlier report, at the line that now holds their old text."""
    out = []
    for d in json.loads(report.read_text())["mutants"]:
        if d["verdict"].startswith("killed"):
            continue
        path = ROOT / PKG / d["path"]
        lines = [ln.strip() for ln in path.read_text(encoding="utf-8").splitlines()]
        hits = [i for i, ln in enumerate(lines) if ln == d["old"]]
        if not hits:
            print(f"gone: {d['path']}:{d['line']} {d['old']!r} (the line was changed)")
            continue
        i = min(hits, key=lambda k: abs(k + 1 - d["line"]))
        tree = ast.parse("\n".join(path.read_text(encoding="utf-8").splitlines()))
        inner = [f for f in _functions(tree) if f[0] <= i + 1 <= f[1]]
        fn = max(inner, key=lambda f: f[0]) if inner else None
        out.append(Mutant(d["path"], i + 1, d["kind"], d["old"], d["new"],
                          function=fn[2] if fn else "", first_line=fn[3] if fn else 0,
                          curated=d.get("curated", "")))
    return out


def run(chosen: list[Mutant], args: argparse.Namespace) -> int:
    """Run the mutants in a copy of the repository; print and (``--report``) save the score."""
    work = copy_repo()
    (work / "_mutation_tracer.py").write_text(TRACER)
    select = work / "_mutation_select.txt"
    t_start = time.perf_counter()
    try:
        calls = call_map(work, timeout=3600, tests=args.tests)
        for i, m in enumerate(chosen, 1):
            m.tests = tests_for(m, calls)
            if not m.tests:
                m.verdict = "not covered"
            else:
                original = apply(work, m)
                select.write_text("\n".join(m.tests))
                files = sorted({t.split("::")[0] for t in m.tests})
                try:
                    code, m.seconds, _ = run_pytest(work, ["-x", *files], args.timeout,
                                                    {"PFSDM_MUTATION_SELECT": str(select)})
                finally:
                    (work / PKG / m.path).write_text(original, encoding="utf-8")
                m.verdict = ("killed (timeout)" if code == -1 else
                             "survived" if code == 0 else "killed")
            print(f"[{i}/{len(chosen)}] {m.verdict:16s} {m.ident} ({m.seconds:.0f} s, "
                  f"{len(m.tests)} tests)", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)

    killed = sum(m.verdict.startswith("killed") for m in chosen)
    total = time.perf_counter() - t_start
    print(f"\nkilled {killed} of {len(chosen)} mutants ({100 * killed / len(chosen):.0f} %) "
          f"in {total / 60:.1f} min")
    survivors = [m for m in chosen if not m.verdict.startswith("killed")]
    if survivors:
        print("\nsurvivors (judge each: a missing test, or an equivalent mutant):")
        for m in survivors:
            print(f"- {m.verdict}: {m.ident} in {m.function or '(module level)'}\n"
                  f"    {m.old}\n  → {m.new}" + (f"\n    ({m.curated})" if m.curated else ""))
    if args.report:
        args.report.write_text(json.dumps(
            {"killed": killed, "total": len(chosen), "minutes": total / 60,
             "mutants": [asdict(m) for m in chosen]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
