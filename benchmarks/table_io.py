"""Writing and reading a large feature table: CSV against Parquet.

Run from the repository root (needs pyarrow: ``pip install -e ".[parquet]"``)::

    .venv/bin/python benchmarks/table_io.py                 # 50,000 rows x 350 columns
    .venv/bin/python benchmarks/table_io.py --rows 5000

A table shaped like ``pfsdm measure``'s (movie, frame, label, track_id, a text column of
warnings, a boolean, and float feature columns up to 350 columns in all) is written with
:func:`napari_pfsdm.write_table` and read back with :func:`napari_pfsdm.read_table` as
``.csv`` and as ``.parquet`` (both with their sidecar, both atomic) in a temporary folder; the
table prints seconds and file sizes, and checks that both read back equal to what was written.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd


def make_table(rows: int, columns: int, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    keys = pd.DataFrame({
        "movie": np.repeat([f"movie{i:02d}" for i in range(10)], -(-rows // 10))[:rows],
        "frame": np.arange(rows) // 250,
        "label": np.arange(rows) % 250 + 1,
        "track_id": np.arange(rows) % 250,
        "touches_border": rng.random(rows) < 0.05,
        "warnings": np.where(rng.random(rows) < 0.05, "touches the image border", ""),
    })
    n_float = columns - keys.shape[1]
    feats = pd.DataFrame(rng.random((rows, n_float)),
                         columns=[f"shape_r{i // 11:02d}_n{i % 11:02d}" for i in range(n_float)])
    return pd.concat([keys, feats], axis=1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rows", type=int, default=50_000)
    ap.add_argument("--columns", type=int, default=350)
    args = ap.parse_args(argv)
    from napari_pfsdm import read_table, write_table
    from napari_pfsdm.core.table_options import plain

    table = make_table(args.rows, args.columns)
    print(f"{args.rows:,} rows x {table.shape[1]} columns")
    print("| format | write (s) | read (s) | file (MB) | read back equal |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in (".csv", ".parquet"):
            path = Path(tmp) / f"features{suffix}"
            t0 = time.perf_counter()
            write_table(table, path, {"n_fourier": 10}, table_type="features")
            t_write = time.perf_counter() - t0
            t0 = time.perf_counter()
            back = read_table(path)
            t_read = time.perf_counter() - t0
            try:
                pd.testing.assert_frame_equal(plain(back), table)
                same = "yes, dtypes included"
            except AssertionError as exc:
                same = f"no: {str(exc).splitlines()[0]}"
            print(f"| {suffix[1:]} | {t_write:.2f} | {t_read:.2f} | "
                  f"{path.stat().st_size / 1e6:.0f} | {same} |")
    # what the sidecar's fingerprint of the content adds to every write (and to a read whose
    # bytes are not those its sidecar records: a copy re-saved by pandas)
    from napari_pfsdm.io.sidecar import content_summary

    t0 = time.perf_counter()
    content_summary(table)
    print(f"\nthe sidecar's content fingerprint: {time.perf_counter() - t0:.2f} s "
          "(part of each write above)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
