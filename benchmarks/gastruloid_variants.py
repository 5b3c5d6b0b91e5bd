"""Which PF-SDM classification variants help on the synthetic gastruloids (development seeds).

The gastruloid report (``benchmarks/gastruloids.py``) uses one fixed pipeline: the chosen
frames' PF-SDM magnitudes concatenated, standardised, L2 logistic regression with C = 0.01.
This script measures the variants tried while looking for a better one, on generator seeds
that are *not* the report's seed 0, with the same nested protocol (20 splits per seed):

    python benchmarks/gastruloid_variants.py                 # seeds 1 2, frames 0-9
    python benchmarks/gastruloid_variants.py --seeds 1 2 3 --frames 0-12

It prints balanced accuracy (shape, intensity, nested fusion, test-tuned fusion), mean over the
seeds, and writes ``benchmarks/out/gastruloid_variants.csv``. No pixel baselines here: they
take minutes per seed; ``benchmarks/gastruloids.py --seeds ...`` runs them on the same splits.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from sklearn.decomposition import PCA
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from napari_pfsdm import DEFAULTS
from napari_pfsdm.analysis import classification as cl
from napari_pfsdm.data.gastruloids import make_gastruloids

OUT = Path(__file__).parent / "out"
ROWS = ["shape", "intensity", "fusion (nested)", "fusion (optimistic, test-tuned)"]


def _model(xs, xi, y, make):
    def fit(x, tr, pr):
        clf = make()
        clf.fit(x[tr], y[tr])
        return clf.predict_proba(x[pr])[:, 1]

    return lambda tr, pr: (fit(xs, tr, pr), fit(xi, tr, pr))


def _logistic(C=0.01, scale=True, pca=None):
    def make():
        steps = [StandardScaler()] if scale else []
        if pca:
            steps += [PCA(pca), StandardScaler()]
        steps.append(LogisticRegression(C=C, class_weight="balanced", solver="liblinear",
                                        max_iter=1000, random_state=0))
        return make_pipeline(*steps)

    return make


def _blocks(x, n_frames):
    """(n, n_frames * n_radii * (n_fourier + 1)) -> (n, n_frames, n_radii, n_fourier + 1)."""
    return x.reshape(len(x), n_frames, -1, DEFAULTS["n_fourier"] + 1)


def variants(table, data, frames):
    """name -> (x_shape, x_intensity, model factory)."""
    f = len(frames)
    xs, _ = cl.feature_matrix(table, "shape", frames)
    xi, _ = cl.feature_matrix(table, "intensity", frames)
    xs9, _ = cl.feature_matrix(table, "shape", frames[-1:])
    xi9, _ = cl.feature_matrix(table, "intensity", frames[-1:])
    xs0, _ = cl.feature_matrix(table, "shape", frames[:1])
    xi0, _ = cl.feature_matrix(table, "intensity", frames[:1])
    growth, contrast = cl.size_contrast_features(data.labels, data.intensity, frames)
    ringsum = lambda x, k: _blocks(x, k).sum(2).reshape(len(x), -1)  # noqa: E731
    heavy = int(xs.shape[1] / f)  # repeat a scalar as often as one frame has PF-SDM features
    out = {
        "report pipeline (C=0.01)": (xs, xi, _logistic(0.01)),
        "C=0.1": (xs, xi, _logistic(0.1)),
        "C=1": (xs, xi, _logistic(1.0)),
        "not standardised, C=0.1": (xs, xi, _logistic(0.1, scale=False)),
        "PCA 10 in the training split": (xs, xi, _logistic(0.1, pca=10)),
        "last frame only": (xs9, xi9, _logistic(0.01)),
        "last - first frame": (xs9 - xs0, xi9 - xi0, _logistic(0.1)),
        "ring-summed spectrum (11/frame)": (ringsum(xs, f), ringsum(xi, f), _logistic(0.1)),
        "log magnitudes": (np.log(xs + 1e-3), np.log(xi + 1e-3), _logistic(0.1)),
        "PF-SDM + growth/contrast (weighted)": (
            np.hstack([xs, np.repeat(growth, heavy, 1)]),
            np.hstack([xi, np.repeat(contrast, heavy, 1)]),
            _logistic(0.1),
        ),
        "size + contrast only (report's ref.)": (growth, contrast, _logistic(1.0)),
    }
    return out


def main(argv=None) -> pd.DataFrame:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    p.add_argument("--frames", default="0-9")
    p.add_argument("--repeats", type=int, default=4, help="repeats of 5 x 20 %% splits")
    a = p.parse_args(argv)
    warnings.filterwarnings("ignore", category=FutureWarning)
    frames = cl.parse_frames(a.frames)
    rows = []
    for seed in a.seeds:
        t0 = time.perf_counter()
        data = make_gastruloids(seed=seed)
        table = cl.measure_movies(data.labels, data.intensity, frames=frames)
        y = data.multi_axis.astype(int)
        splits = cl.make_splits(y, n_repeats=a.repeats, seed=seed)
        print(f"seed {seed}: data and features {time.perf_counter() - t0:.1f} s", flush=True)
        for name, (xs, xi, make) in variants(table, data, frames).items():
            s = cl.summarize(cl.evaluate(_model(xs, xi, y, make), y, splits, seed=seed))
            for feat in ROWS:
                rows.append({"seed": seed, "variant": name, "features": feat,
                             "balanced_accuracy": s.loc[feat, "balanced_accuracy_mean"]})
    res = pd.DataFrame(rows)
    wide = res.pivot_table(index="variant", columns="features", values="balanced_accuracy",
                           sort=False)[ROWS]
    per_seed = res[res.features == "fusion (nested)"].pivot_table(
        index="variant", columns="seed", values="balanced_accuracy", sort=False)
    wide.columns = ["shape", "intensity", "fusion nested", "fusion test-tuned"]
    wide = wide.join(per_seed.add_prefix("nested, seed "))
    with pd.option_context("display.width", 160, "display.precision", 3):
        print(f"\nbalanced accuracy, mean over seeds {a.seeds}, frames {a.frames}, "
              f"{5 * a.repeats} splits per seed")
        print(wide.to_string())
    OUT.mkdir(exist_ok=True)
    res.to_csv(OUT / "gastruloid_variants.csv", index=False)
    print(f"wrote {OUT / 'gastruloid_variants.csv'}")
    return res


if __name__ == "__main__":
    main()
