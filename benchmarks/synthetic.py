"""The paper's synthetic five-shape benchmark: PF-SDM against EFA and GPA.

Run from the repository root::

    .venv/bin/python benchmarks/synthetic.py            # PF-SDM default + baselines (seconds)
    .venv/bin/python benchmarks/synthetic.py --full     # every PF-SDM variant (minutes)

Five base shapes (circle, elongated, folded, rounded square, branched), each under
``--n-per-class`` random translations, rotations, reflections and 0.5×–2× scalings, as exact
copies and as mildly perturbed copies. Prints the silhouette (5 true classes) and the
leave-one-out 1-NN accuracy of every distance matrix, and writes
``synthetic_benchmark.csv`` and ``synthetic_mds.png`` to ``--out``. The work is done by
:func:`run` of ``examples/synthetic_five_shapes.py`` (also what ``pfsdm demo`` runs).
"""

from __future__ import annotations

import os

# One BLAS/OpenMP thread: on a shared machine, multi-threaded BLAS spinning against other
# processes made single calls up to 500x slower (measured here).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))

from synthetic_five_shapes import run  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="benchmarks/out", help="output folder")
    parser.add_argument("--full", action="store_true",
                        help="every PF-SDM mapping x sdf x normalization x rings x invariance")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-per-class", type=int, default=10)
    parser.add_argument("--size", type=int, default=256, help="masks are size x size pixels")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    run(args.out, seed=args.seed, quick=not args.full, n_per_class=args.n_per_class,
        size=args.size)
    print(f"total {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
