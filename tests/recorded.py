"""Numbers recorded from the package, which later versions must reproduce (imported by the
tests; ``python tests/recorded.py`` writes the files again).

* ``data/pca_montage.npz``: the feature table of ``pf.measure`` on
  ``make_timelapse_montage(seed=0)`` (the input, stored so that the PCA's numbers do not move
  when the features do) and its PCA scores and explained-variance ratios, weighted,
  standardised and with classic measures regressed out.
* ``data/fusion.json``: the late-fusion protocol's results on synthetic features
  (:func:`fusion_matrices`, :func:`fusion_table`, built here from fixed seeds):
  ``classification.evaluate`` (inner CV and hold-out), ``predict_outcome`` (default call and
  variants).

The PCA and ``classification.evaluate`` were recorded with the numpy SVD PCA and the two
fusion loops of commit aca1214; ``predict_outcome`` with its fusion weights chosen by the
out-of-fold log-loss and the classic measures' C = 10 (any number of groups). The tests hold
the package to them at 1e-10 (scores, probabilities) and exactly (accuracies, weights).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

DATA = Path(__file__).resolve().parent / "data"
PCA_FILE = DATA / "pca_montage.npz"
FUSION_FILE = DATA / "fusion.json"

#: The classic measures regressed out in the recorded "beyond" PCA (the plugin's choice).
REGRESSED = ("area", "circularity", "eccentricity", "solidity", "axis_major_length",
             "axis_minor_length")
#: (name, keywords of pca_scores / ShapePCA) of the recorded PCAs.
PCA_CASES = {
    "shape": {"channel": "shape", "n_components": 5},
    "intensity": {"channel": "intensity", "n_components": 5},
    "shape_standardized": {"channel": "shape", "n_components": 3, "standardize": True},
    "intensity_standardized": {"channel": "intensity", "n_components": 3, "standardize": True},
}


# --------------------------------------------------------------------------- PCA input
def montage_table() -> pd.DataFrame:
    """``pf.measure`` of the montage (seed 0) as stored: its numeric columns and options."""
    from napari_pfsdm.core.table_options import set_options

    data = np.load(PCA_FILE, allow_pickle=False)
    table = pd.DataFrame(data["table"], columns=[str(c) for c in data["columns"]])
    for col in ("frame", "label"):
        table[col] = table[col].astype(np.int64)
    table["error"] = ""
    return set_options(table, json.loads(str(data["options"])))


def montage_groups() -> dict[int, str]:
    """The montage's groups (label -> group), as stored."""
    data = np.load(PCA_FILE, allow_pickle=False)
    return {int(k): str(g) for k, g in zip(data["group_labels"], data["groups"], strict=True)}


# ------------------------------------------------------------------------ fusion input
def fusion_matrices(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shape and intensity vectors of 40 objects (16 of group 1): the shape carries the group
    more strongly than the intensity, as in the paper's gastruloids."""
    rng = np.random.default_rng(seed)
    y = np.array([1] * 16 + [0] * 24)
    xs = rng.normal(size=(40, 12)) + 0.6 * y[:, None] * (np.arange(12) < 4)
    xi = rng.normal(size=(40, 9)) + 0.4 * y[:, None] * (np.arange(9) < 3)
    return xs, xi, y


def fusion_table(seed: int = 0) -> tuple[pd.DataFrame, dict[int, str]]:
    """A feature table of 30 objects over 4 frames with shape, intensity and classic columns,
    and each object's group (12 "b", 18 "a"): the group shows more in later frames."""
    rng = np.random.default_rng(seed)
    n, frames = 30, 4
    group = np.array(["b"] * 12 + ["a"] * 18)
    rows = []
    for t in range(frames):
        strength = 0.3 + 0.2 * t
        for k in range(n):
            g = float(group[k] == "b")
            row = {"frame": t, "label": k + 1, "error": ""}
            for r in range(2):
                for m in range(4):
                    row[f"shape_r{r:02d}_n{m:02d}"] = rng.normal() + strength * g * (m == 2)
                    row[f"intensity_r{r:02d}_n{m:02d}"] = rng.normal() + 0.5 * strength * g * (
                        m == 1)
            row["area"] = 500 + 40 * rng.normal() + 15 * g
            row["circularity"] = 0.8 + 0.05 * rng.normal() - 0.02 * g
            row["intensity_mean"] = 1 + 0.1 * rng.normal()
            rows.append(row)
    table = pd.DataFrame(rows)
    return table, {k + 1: str(group[k]) for k in range(n)}


# -------------------------------------------------------------------------- the runs
def pca_runs(table: pd.DataFrame) -> dict[str, np.ndarray]:
    """Every recorded PCA of ``table``: ``{name}_scores`` and ``{name}_ratio``."""
    from napari_pfsdm.analysis.reduction import pca_scores
    from napari_pfsdm.analysis.shape_space import ShapePCA
    from napari_pfsdm.core.table_schema import pc_columns

    out = {}
    for name, kw in PCA_CASES.items():
        scores, ratio = pca_scores(table, kw["channel"], kw["n_components"],
                                   standardize=kw.get("standardize", False))
        out[f"{name}_scores"] = scores[pc_columns(scores.columns, kw["channel"])].to_numpy()
        out[f"{name}_ratio"] = np.asarray(ratio, float)
    space = ShapePCA(n_components=4, regress_out=REGRESSED).fit(table)
    scores = space.transform(table)
    out["beyond_scores"] = scores[pc_columns(scores.columns, "shape")].to_numpy()
    out["beyond_ratio"] = np.asarray(space.explained_variance_ratio_, float)
    return out


def _plain(value):
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _rows(frame: pd.DataFrame) -> list[dict]:
    """The rows of ``frame`` as JSON-ready dicts (floats kept exactly: JSON writes repr)."""
    return [{str(k): _plain(v) for k, v in row.items()} for row in frame.to_dict("records")]


def fusion_runs(part: str) -> dict:
    """The fusion protocol's results (JSON-ready): ``part`` "evaluate" (the classification
    helpers) or "predict" (``predict_outcome``)."""
    from napari_pfsdm.analysis import classification as cl
    from napari_pfsdm.analysis.outcome import predict_outcome

    out: dict = {}
    if part == "evaluate":
        for seed in (0, 1, 2):
            xs, xi, y = fusion_matrices(seed)
            splits = cl.make_splits(y, n_splits=5, n_repeats=2, seed=seed)
            for inner in ("cv", "holdout"):
                scores = cl.evaluate(cl.logistic_model(xs, xi, y), y, splits, inner=inner,
                                     seed=seed)
                out[f"{seed}-{inner}"] = _rows(scores)
        return out
    table, groups = fusion_table(0)
    some = {k: g for k, g in groups.items() if k <= 24}  # 6 objects to predict only
    calls = {
        "default": dict(groups=groups),
        "seed3": dict(groups=groups, seed=3, n_repeats=1),
        "two_channels": dict(groups=groups, channels=["shape", "intensity"], frames=[0, 1, 2]),
        "unlabelled": dict(groups=some, frames=[2, 3], curve=False),
    }
    montage, montage_groups_ = montage_table(), montage_groups()
    for name, kw in calls.items():
        pred = predict_outcome(table, **kw)
        out[name] = _prediction(pred)
    pred = predict_outcome(montage, montage_groups_)
    out["montage"] = _prediction(pred)
    return out


def _prediction(pred) -> dict:
    scores = pred.scores.copy()
    return {"scores": _rows(scores), "summary": _rows(pred.summary.reset_index()),
            "curve": _rows(pred.curve), "probabilities": _rows(pred.probabilities)}


def record() -> None:  # pragma: no cover - run by hand
    import napari_pfsdm as pf
    from napari_pfsdm.data.gastruloids import make_timelapse_montage

    DATA.mkdir(exist_ok=True)
    labels, intensity, groups = make_timelapse_montage(seed=0)
    measured = pf.measure(labels, intensity)
    assert (measured["error"] == "").all()
    numeric = [c for c in measured.columns
               if pd.api.types.is_numeric_dtype(measured[c]) and c != "touches_border"]
    inputs = dict(table=measured[numeric].to_numpy(float), columns=np.array(numeric),
                  options=json.dumps(measured.attrs["pfsdm"]),
                  group_labels=np.array(sorted(groups)),
                  groups=np.array([groups[k] for k in sorted(groups)]))
    np.savez_compressed(PCA_FILE, **inputs)
    runs = pca_runs(measured)
    for key, value in pca_runs(montage_table()).items():  # the stored table: the same numbers
        np.testing.assert_array_equal(value, runs[key])
    np.savez_compressed(PCA_FILE, **inputs, **runs)
    runs = {part: fusion_runs(part) for part in ("evaluate", "predict")}
    FUSION_FILE.write_text(json.dumps(runs) + "\n", encoding="utf-8")


if __name__ == "__main__":  # pragma: no cover
    record()
