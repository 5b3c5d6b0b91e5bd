"""The elastic term's compiled kernel against an earlier one from git, per pair, on one thread.

On the first ``--objects`` MPEG-7 shapes (all pairs), one after the other in this process, each
timed as CPU time (numba and BLAS on one thread, compiled before the timing, least of
``--repeat`` runs):

- ``D_PF``: :func:`napari_pfsdm.distance_matrix` on their default embeddings (the anchor);
- ``d_E`` of the kernel at ``--ref`` (``src/napari_pfsdm/core/elastic.py`` read with
  ``git show`` into a temporary module, its own numba cache; a revision whose ``elastic.py``
  holds its kernels itself, ``c9e5a94`` or earlier: a later one imports this checkout's
  ``elastic_kernel``);
- ``d_E`` of this checkout's kernel (:func:`napari_pfsdm.core.elastic.elastic_distance_matrix`,
  the library's settings);

and the largest relative difference between the two kernels' distances, and the cost of
``distance_matrix(..., elastic_weight=μ)`` over the default's (any μ > 0), (D_PF + d_E) / D_PF
per pair.

The shapes' signatures and embeddings are those that ``benchmarks/mpeg7_elastic.py`` caches in
``$TMPDIR/napari_pfsdm_mpeg7/elastic_features2.npz`` (run it first). Run (repository root)::

    .venv/bin/python benchmarks/elastic_kernel.py

Quote ratios from one run: the machine is shared, absolute times move with its load.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"  # before numpy and numba are imported

import numpy as np  # noqa: E402

from napari_pfsdm.core.distances import distance_matrix  # noqa: E402
from napari_pfsdm.core.elastic import elastic_distance_matrix  # noqa: E402
from napari_pfsdm.core.embeddings import Embeddings  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FEATURES = Path(tempfile.gettempdir()) / "napari_pfsdm_mpeg7" / "elastic_features2.npz"
#: The kernels built as closures inside one function (numba's cache missed them in every
#: process), before they became module-level functions with arguments: the same arithmetic,
#: so the distances must be identical (the default ``--ref``; ``aa7ac98``: before the bounds
#: were kept to searches with a limit; ``dea0ee6``: before the shared cost diagonals).
REF = "c9e5a94"


def module_at(ref: str, tmp: Path):
    """``napari_pfsdm.core.elastic`` as of git ``ref``, loaded from a file of its own (so that
    numba caches its compiled kernels apart from this checkout's)."""
    src = subprocess.run(["git", "show", f"{ref}:src/napari_pfsdm/core/elastic.py"], cwd=ROOT,
                         check=True, capture_output=True, text=True).stdout
    name = f"_elastic_at_{ref.replace('/', '_').replace('-', '_').replace('.', '_')}"
    path = tmp / f"{name}.py"
    path.write_text(src)
    # a submodule of napari_pfsdm.core, so that its relative imports resolve
    spec = importlib.util.spec_from_file_location(f"napari_pfsdm.core.{name}", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def cpu_time(fn, repeat: int):
    """The least CPU time of ``repeat`` calls, and the last call's result."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t0)
    return best, out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--objects", type=int, default=500)
    p.add_argument("--ref", default=REF, help="git revision of the kernel to compare with")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    if not FEATURES.exists():
        sys.exit(f"{FEATURES} missing: run benchmarks/mpeg7_elastic.py first")
    f = np.load(FEATURES)
    n = args.objects
    sig = f["sig"][:n]
    emb = Embeddings(f["emb"][:n], f["weights"], f["mode_weights"], outline=f["outline"][:n])
    n_pairs = n * (n - 1) // 2
    with tempfile.TemporaryDirectory() as tmp:
        old = module_at(args.ref, Path(tmp))
        # compiled outside the timing
        distance_matrix(Embeddings(f["emb"][:20], f["weights"], f["mode_weights"],
                                   outline=f["outline"][:20]))
        old.elastic_distance_matrix(sig[:20])
        elastic_distance_matrix(sig[:20])
        t_pf, _ = cpu_time(lambda: distance_matrix(emb), args.repeat)
        t_old, d_old = cpu_time(lambda: old.elastic_distance_matrix(sig), args.repeat)
        t_new, d_new = cpu_time(lambda: elastic_distance_matrix(sig), args.repeat)
    iu = np.triu_indices(n, 1)
    a, b = d_old[iu], d_new[iu]
    rel = float(np.max(np.abs(a - b) / np.maximum(np.abs(a), 1e-12)))
    us = 1e6 / n_pairs
    print(f"{n} MPEG-7 shapes, {n_pairs:,} pairs; CPU time per pair, one thread, least of "
          f"{args.repeat} runs\n")
    print(f"| distance | µs per pair | (D_PF + d_E) / D_PF |\n|---|---|---|\n"
          f"| D_PF (`distance_matrix`) | {t_pf * us:.1f} | |\n"
          f"| d_E, kernel at `{args.ref}` | {t_old * us:.1f} | {(t_pf + t_old) / t_pf:.2f} |\n"
          f"| d_E, this kernel | {t_new * us:.1f} | {(t_pf + t_new) / t_pf:.2f} |\n")
    print(f"largest relative difference of the two kernels' d_E: {rel:.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
