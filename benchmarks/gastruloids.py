"""Synthetic gastruloids: predict single vs multiple body axes from early frames.

PF-SDM shape + intensity features with logistic regression and late fusion (nested and the
paper's optimistic, test-tuned fusion weight), against pixel-space baselines (scikit-learn on
downsampled pixels; a small CNN when torch is installed), on the same splits, timed end to end.

    python benchmarks/gastruloids.py --out results/gastruloids          # full run
    python benchmarks/gastruloids.py --out results/gastruloids --quick  # smoke run

Writes gastruloid_results.csv, gastruloid_accuracy.png and gastruloid_pca.png in --out: the
report of ``examples/gastruloid_report.py``.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))

from gastruloid_report import main  # noqa: E402

if __name__ == "__main__":
    main()
