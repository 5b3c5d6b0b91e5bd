"""The tables every measuring path makes of fixed inputs, as CSV text (the golden test's
reference, ``tests/data/golden/``).

``python tests/golden_tables.py`` writes them; ``tests/test_golden_tables.py`` compares each
path's table of today's code with them, byte for byte. Regenerate only when a change of the
tables is meant, and say so in the commit.
"""

from __future__ import annotations

import gzip
import sys
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).parent / "data" / "golden"


def inputs() -> dict[str, tuple]:
    """name -> (labels, intensity, measure keywords)."""
    from napari_pfsdm.data.gastruloids import make_timelapse_montage
    from napari_pfsdm.data.volumes import blob_volume

    labels, reporter, _ = make_timelapse_montage(4, 6, 160, seed=5)
    spacing = (2.0, 1.0, 1.0)
    volume = np.zeros((2, 16, 32, 64), np.uint16)
    for t in range(2):
        volume[t, :, :, :32][blob_volume("tetrahedron", size=(16, 32, 32), radius=7 + t,
                                         spacing=spacing)] = 1
        volume[t, :, :, 32:][blob_volume("line", size=(16, 32, 32), radius=7,
                                         spacing=spacing)] = 2
    return {
        "timelapse": (labels, reporter, {}),
        "timelapse_shape_only": (labels, None, {}),
        "midline_elastic": (labels[:2], reporter[:2],
                            {"profile_bins": 6, "elastic_signature": "table", "n_fourier": 8,
                             "border_objects": "leave_out"}),
        "volumes": (volume, None, {"axes": "tzyx", "spacing": spacing}),
    }


def csv_text(table: pd.DataFrame) -> str:
    """The table as the package writes it (plain CSV, exact floats)."""
    import tempfile

    from napari_pfsdm.io.tables import write_table

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "t.csv"
        write_table(table, path, table.attrs.get("pfsdm") or {})
        return path.read_text()


def reference(name: str) -> str:
    with gzip.open(HERE / f"{name}.csv.gz", "rt") as f:
        return f.read()


def main() -> None:
    import napari_pfsdm as pf

    HERE.mkdir(parents=True, exist_ok=True)
    for name, (labels, intensity, kw) in inputs().items():
        table = pf.measure(labels, intensity, **kw)
        text = csv_text(table)
        with gzip.open(HERE / f"{name}.csv.gz", "wt", compresslevel=9) as f:
            f.write(text)
        print(name, table.shape, len(text))


if __name__ == "__main__":
    sys.exit(main())
