"""What the principal components mean: classic shape measures and their correlation with the PCs.

PF-SDM features are not directly readable, and their first principal component is often a
familiar quantity: on the bundled gastruloid sample PC1 explains 96 % of the variance and
follows circularity (r ≈ 0.99). :func:`table_measures` takes the classic numbers from a
feature table's own regionprops columns (what a person sees in the table and plots, and costs
nothing more to compute), :func:`outline_measures` computes them from one outline;
:func:`explain_components` says, in words, which of them each PC follows.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from .tables import match_rows

__all__ = ["MEASURES", "table_measures", "outline_measures", "component_correlations",
           "explain_components"]

#: Classic measures, with the words used to explain a component (higher value → ...).
MEASURES = {
    "circularity": ("circularity (4πA/P²)", "rounder"),
    "aspect_ratio": ("minor/major axis ratio", "less elongated"),
    "solidity": ("solidity (area / convex hull)", "less indented"),
}


def table_measures(table: pd.DataFrame) -> pd.DataFrame:
    """The :data:`MEASURES` of every row of a 2-D feature table, from its classic columns
    (:mod:`napari_pfsdm.analysis.classic`: scikit-image's regionprops of the labelled pixels).

    ``circularity`` and ``solidity`` are the table's own; ``aspect_ratio`` is
    ``axis_minor_length / axis_major_length`` (regionprops' second moments; NaN where the major
    axis is 0, a one-pixel object). Replaces computing :func:`outline_measures` for every
    object of a run (0.17 ms each, 8 % of the measuring; the two agree to r ≥ 0.98 on the
    bundled sample, the same words for its PCs).

    Returns
    -------
    DataFrame
        ``movie`` (when the table has movies), ``frame``, ``label`` and the :data:`MEASURES`
        columns, one row per table row (``frame`` 0 when the table has none).
    """
    major = table["axis_major_length"].to_numpy(float)
    minor = table["axis_minor_length"].to_numpy(float)
    ratio = np.full(len(major), np.nan)
    np.divide(minor, major, out=ratio, where=major > 0)
    frames = (table["frame"].to_numpy() if "frame" in table
              else np.zeros(len(table), np.int64))
    keys = {"movie": table["movie"].to_numpy()} if "movie" in table.columns else {}
    return pd.DataFrame({**keys, "frame": frames, "label": table["label"].to_numpy(),
                         "circularity": table["circularity"].to_numpy(float),
                         "aspect_ratio": ratio,
                         "solidity": table["solidity"].to_numpy(float)})


def outline_measures(points: np.ndarray) -> dict[str, float]:
    """Circularity, minor/major axis ratio and solidity of a closed outline.

    Parameters
    ----------
    points : ndarray, shape (M, 2)
        The outline, without the closing point (e.g. ``result.contour.points``).

    Returns
    -------
    dict
        ``circularity`` = 4πA/P² (1 for a disk), ``aspect_ratio`` = √(λmin/λmax) of the
        polygon's second moments (1 for a disk), ``solidity`` = A / convex-hull area.

    Examples
    --------
    >>> t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    >>> m = outline_measures(np.c_[10 * np.sin(t), 5 * np.cos(t)])
    >>> round(m["aspect_ratio"], 3), round(m["solidity"], 3)
    (0.5, 1.0)
    """
    p = np.asarray(points, float)
    q = np.roll(p, -1, axis=0)
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    area = 0.5 * cross.sum()
    perimeter = np.hypot(*(q - p).T).sum()
    nan = {k: float("nan") for k in MEASURES}
    if abs(area) < 1e-12 or perimeter == 0:
        return nan
    # second moments of the polygon's area (Green's theorem), about its centroid
    c = ((p + q) * cross[:, None]).sum(axis=0) / (6 * area)
    x, y = (p - c).T
    xq, yq = (q - c).T
    cr = x * yq - xq * y
    ixx = (cr * (x * x + x * xq + xq * xq)).sum() / 12
    iyy = (cr * (y * y + y * yq + yq * yq)).sum() / 12
    ixy = (cr * (x * yq + 2 * x * y + 2 * xq * yq + xq * y)).sum() / 24
    lam = np.linalg.eigvalsh(np.array([[ixx, ixy], [ixy, iyy]]) / area)
    # imported here: the napari panel imports this module when docked, and scipy.spatial
    # costs ~0.2 s there (docs/design.md §5, "So is the measuring code")
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(p).volume
    except QhullError:
        hull = abs(area)
    return {
        "circularity": float(4 * np.pi * abs(area) / perimeter**2),
        "aspect_ratio": float(np.sqrt(max(lam[0], 0.0) / lam[1])) if lam[1] > 0 else np.nan,
        "solidity": float(abs(area) / hull) if hull > 0 else np.nan,
    }


def component_correlations(scores: pd.DataFrame, measures: pd.DataFrame) -> pd.DataFrame:
    """Pearson r between each PC column of ``scores`` and each measure.

    Both tables have ``frame`` and ``label`` (and ``movie`` for many movies); rows are matched
    on all of them (:func:`~napari_pfsdm.analysis.tables.match_rows`), NaNs left out. The PC
    columns are ``PC1`` … or, as :func:`~napari_pfsdm.analysis.reduction.pca_scores` names
    them, ``shape_PC1`` …. Returns a DataFrame: one row per PC (``PC1``…), one column per
    measure.
    """
    pcs = [c for c in scores.columns if re.fullmatch(r"(\w+_)?PC\d+", str(c))]
    cols = [c for c in MEASURES if c in measures.columns]
    at = match_rows(scores, measures)
    left = scores[pcs].to_numpy(float)[at >= 0][:, :, None]  # rows × PCs × 1
    right = measures[cols].to_numpy(float)[at[at >= 0]][:, None, :]  # rows × 1 × measures
    ok = np.isfinite(left) & np.isfinite(right)  # the rows of each pair
    n = ok.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        da = np.where(ok, left - np.where(ok, left, 0).sum(axis=0) / n, 0.0)
        db = np.where(ok, right - np.where(ok, right, 0).sum(axis=0) / n, 0.0)
        r = (da * db).sum(axis=0) / np.sqrt((da**2).sum(axis=0) * (db**2).sum(axis=0))

    def varies(x):  # not one value over the pair's rows (a variance can round above 0)
        return np.where(ok, x, -np.inf).max(axis=0) > np.where(ok, x, np.inf).min(axis=0)

    out = np.where((n > 2) & varies(left) & varies(right), np.clip(r, -1.0, 1.0), np.nan)
    return pd.DataFrame(out, index=[str(c).rsplit("_", 1)[-1] for c in pcs], columns=cols)


def explain_components(scores: pd.DataFrame, measures: pd.DataFrame,
                       ratios=None, n: int = 2, threshold: float = 0.7) -> list[str]:
    """Plain-words sentences on the first ``n`` PCs: which classic measure each follows.

    A PC "follows" a measure when |r| ≥ ``threshold``; otherwise the sentence says it is none of
    them (a finer shape difference that the classic numbers miss).

    Examples
    --------
    >>> s = pd.DataFrame({"frame": [0, 0, 0], "label": [1, 2, 3], "PC1": [1.0, 2.0, 3.1]})
    >>> m = pd.DataFrame({"frame": [0, 0, 0], "label": [1, 2, 3],
    ...                   "circularity": [0.5, 0.7, 0.9]})
    >>> explain_components(s, m, [0.9], n=1)
    ['PC1 (90 %) follows circularity (4πA/P²), r = +1.00: rounder to the right']
    """
    corr = component_correlations(scores, measures)
    out = []
    for k, pc in enumerate(corr.index[:n]):
        share = f" ({100 * ratios[k]:.0f} %)" if ratios is not None and len(ratios) > k else ""
        row = corr.loc[pc].dropna()
        if row.empty:
            continue
        best = row.abs().idxmax()
        r = float(row[best])
        name, higher = MEASURES[best]
        if abs(r) >= threshold:
            side = "right" if r > 0 else "left"
            out.append(f"{pc}{share} follows {name}, r = {r:+.2f}: {higher} to the {side}")
        else:
            out.append(f"{pc}{share} is none of the classic measures (largest |r| = "
                       f"{abs(r):.2f}, {name}): a finer shape difference")
    return out
