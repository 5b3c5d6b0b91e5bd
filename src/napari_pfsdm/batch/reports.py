"""Tables and plots made from a feature table: PCA trajectories, distances, MDS, groups.

Headless: figures are drawn with :class:`matplotlib.figure.Figure` (no pyplot, no GUI
backend) and saved to PNG.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis.features import FOLDED_WARNING
from ..core.table_schema import check_feature_table
from ..io_csv import read_table_csv, save_figure

__all__ = [
    "attach_groups",
    "distance_table",
    "mds_coordinates",
    "object_ids",
    "pca_scores",
    "plot_mds",
    "plot_trajectories",
    "read_groups",
]

KEY_COLUMNS = ("movie", "label")


def object_ids(table: pd.DataFrame) -> pd.Series:
    """One id per object of a table: ``"movie/label"`` (or the label alone without movies)."""
    if "movie" in table.columns:
        return table["movie"].astype(str) + "/" + table["label"].astype(str)
    return table["label"].astype(str)


def row_ids(table: pd.DataFrame) -> list[str]:
    """One id per row: ``movie/t<frame>/l<label>`` (without ``movie/`` when there is none)."""
    base = "t" + table["frame"].astype(str) + "/l" + table["label"].astype(str)
    if "movie" in table.columns:
        base = table["movie"].astype(str) + "/" + base
    return base.tolist()


def read_groups(path: str | os.PathLike) -> pd.DataFrame:
    """Read a groups CSV: a ``group`` column plus ``label`` and/or ``movie`` columns.

    Examples of valid files::

        label,group            movie,group               movie,label,group
        1,single-axis          gastruloid01,single-axis  plate1,3,multi-axes
        2,multi-axes           gastruloid02,multi-axes
    """
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{p}: no such groups file")
    groups = pd.read_csv(p, dtype=str, comment="#")
    groups.columns = [c.strip().lower() for c in groups.columns]
    keys = [k for k in KEY_COLUMNS if k in groups.columns]
    if "group" not in groups.columns or not keys:
        raise ValueError(
            f"{p} must have a 'group' column and a 'label' and/or 'movie' column "
            f"(it has {list(groups.columns)})"
        )
    groups = groups[keys + ["group"]].dropna()
    if groups.duplicated(keys).any():
        raise ValueError(f"{p} gives several groups to the same {'/'.join(keys)}")
    return groups


def attach_groups(table: pd.DataFrame, groups: pd.DataFrame) -> pd.DataFrame:
    """Add a ``group`` column to a feature table (objects without a group get ``""``)."""
    keys = [k for k in KEY_COLUMNS if k in groups.columns]
    missing = [k for k in keys if k not in table.columns]
    if missing:
        raise ValueError(
            f"the groups file has a {missing[0]!r} column but the feature table has none"
        )
    left = table.drop(columns=["group"], errors="ignore").copy()
    attrs = left.attrs
    left.attrs = {}
    for k in keys:
        left["_key_" + k] = left[k].astype(str)
    right = groups.rename(columns={k: "_key_" + k for k in keys})
    out = left.merge(right, on=["_key_" + k for k in keys], how="left")
    out = out.drop(columns=["_key_" + k for k in keys])
    out["group"] = out["group"].fillna("")
    out.attrs = attrs
    return out


def _weighted_features(table: pd.DataFrame, channel: str) -> np.ndarray:
    """Feature vectors scaled by the ring and mode weights, so that Euclidean distances are
    PF-SDM (magnitude) distances."""
    from ..core.distances import weighted_features

    return weighted_features(table, channel=channel)


def pca_scores(
    table: pd.DataFrame, channel: str = "shape", n_components: int = 3
) -> tuple[pd.DataFrame, np.ndarray]:
    """PCA of all (movie, frame, label) rows of a feature table.

    The features of each ring are scaled by the square root of its quadrature weight, so that
    Euclidean distances in this space are the PF-SDM distances (:func:`napari_pfsdm.distance`).
    Rows with an ``error`` are left out.

    Returns
    -------
    scores : DataFrame
        The key columns (``movie``, ``frame``, ``label``, ``group`` when present) and
        ``{channel}_PC1`` … .
    explained : ndarray
        Fraction of the variance explained by each component.
    """
    from sklearn.decomposition import PCA

    ok = table["error"].fillna("").eq("") if "error" in table.columns else slice(None)
    sub = table[ok]
    x = _weighted_features(sub, channel)
    finite = np.isfinite(x).all(axis=1)
    sub, x = sub[finite], x[finite]
    if len(sub) < 2:
        raise ValueError("PCA needs at least two measured objects (rows without error)")
    k = int(min(n_components, x.shape[1], len(sub)))
    pca = PCA(n_components=k)
    z = pca.fit_transform(x)
    keys = [c for c in ("movie", "frame", "label", "group") if c in sub.columns]
    scores = sub[keys].reset_index(drop=True).copy()
    scores.attrs = {}
    for i in range(k):
        scores[f"{channel}_PC{i + 1}"] = z[:, i]
    return scores, pca.explained_variance_ratio_


def distance_table(
    table: pd.DataFrame, intensity_weight: float = 0.0, invariance: str = "magnitude"
) -> pd.DataFrame:
    """Pairwise PF-SDM distance matrix as a square DataFrame indexed by row ids."""
    from ..core.distances import distance_matrix

    d = distance_matrix(table, intensity_weight=intensity_weight, invariance=invariance)
    ids = row_ids(table)
    return pd.DataFrame(d, index=pd.Index(ids, name="object"), columns=ids)


def mds_coordinates(d: np.ndarray, seed: int = 0) -> np.ndarray:
    """2-D metric MDS of a distance matrix (rows with NaN give NaN coordinates)."""
    from sklearn.manifold import MDS

    d = np.asarray(d, float)
    ok = np.isfinite(d).all(axis=1) & (np.isfinite(d).sum(axis=1) > 0)
    ok &= np.isfinite(d[:, ok]).all(axis=1) if ok.any() else ok
    out = np.full((len(d), 2), np.nan)
    if ok.sum() >= 3:
        import inspect

        params = inspect.signature(MDS).parameters
        kw: dict = {"n_components": 2, "random_state": seed}
        if "dissimilarity" in params and "metric_params" not in params:
            kw.update(dissimilarity="precomputed", n_init=4)  # scikit-learn < 1.8
        else:
            kw["metric"] = "precomputed"
            if "init" in params:
                kw["init"] = "classical_mds"
        mds = MDS(**kw)
        out[ok] = mds.fit_transform(d[np.ix_(ok, ok)])
    elif ok.sum() > 0:
        out[ok] = 0.0
    return out


def _colour_key(frame: pd.DataFrame, by: str) -> tuple[np.ndarray, list[str] | None]:
    if by == "group" and "group" in frame.columns:
        names = sorted(set(frame["group"].astype(str)))
        return frame["group"].astype(str).map({n: i for i, n in enumerate(names)}).to_numpy(), names
    return frame["frame"].to_numpy(float), None


def plot_trajectories(
    scores: pd.DataFrame,
    path: str | os.PathLike,
    *,
    components: tuple[int, int] = (1, 2),
    explained: np.ndarray | None = None,
    title: str = "PF-SDM trajectories",
) -> Path:
    """One line per object through time in the PCA plane; points coloured by time or group.

    Several channels (e.g. ``shape_PC*`` and ``intensity_PC*`` columns) give side-by-side
    panels. Returns the PNG path.
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    channels = sorted({c.rsplit("_PC", 1)[0] for c in scores.columns if "_PC" in c},
                      key=lambda c: (c != "shape", c))
    fig = Figure(figsize=(5.2 * len(channels), 4.6), layout="constrained")
    axes = fig.subplots(1, len(channels), squeeze=False)[0]
    by_group = "group" in scores.columns and scores["group"].astype(str).ne("").any()
    ids = object_ids(scores)
    names = sorted(set(scores["group"].astype(str))) if by_group else None
    tab10 = colormaps["tab10"]
    for ax, ch in zip(axes, channels, strict=True):
        cx, cy = (f"{ch}_PC{components[0]}", f"{ch}_PC{components[1]}")
        if cx not in scores or cy not in scores:
            raise ValueError(f"no {cx}/{cy} in the PCA table; choose other components")
        sc = None
        for oid in pd.unique(ids):
            obj = scores[ids == oid].sort_values("frame")
            colour = (tab10(names.index(str(obj["group"].iloc[0])) % 10) if by_group
                      else "0.6")
            ax.plot(obj[cx], obj[cy], "-", color=colour, lw=1.0, alpha=0.7, zorder=1)
            if by_group:
                ax.scatter(obj[cx], obj[cy], s=10, color=colour, zorder=2)
                ax.scatter(obj[cx].iloc[-1:], obj[cy].iloc[-1:], s=40, marker="s",
                           color=colour, edgecolor="k", lw=0.5, zorder=3)
            else:
                sc = ax.scatter(obj[cx], obj[cy], c=obj["frame"], cmap="viridis", s=14,
                                vmin=scores["frame"].min(), vmax=scores["frame"].max(), zorder=2)
        if explained is not None and ch == "shape" and len(explained) >= max(components):
            ev = explained
        else:
            ev = scores.attrs.get(f"{ch}_explained")
        xl, yl = f"PC{components[0]}", f"PC{components[1]}"
        if ev is not None:
            xl += f" ({100 * ev[components[0] - 1]:.2g} % of variance)"
            yl += f" ({100 * ev[components[1] - 1]:.2g} % of variance)"
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_title(f"{ch} features")
        if by_group:
            for i, n in enumerate(names):
                ax.plot([], [], "-o", color=tab10(i % 10), label=n or "(no group)", ms=4)
            ax.legend(fontsize=8, title="group (■ = last frame)", title_fontsize=8)
        elif sc is not None:
            fig.colorbar(sc, ax=ax, label="frame")
    fig.suptitle(title)
    save_figure(fig, path, dpi=120)
    return Path(path)


def plot_mds(
    coords: np.ndarray, table: pd.DataFrame, path: str | os.PathLike, *, title: str = ""
) -> Path:
    """Scatter of 2-D MDS coordinates, coloured by group (or frame), labelled by object."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.6, 4.8), layout="constrained")
    ax = fig.subplots()
    by_group = "group" in table.columns and table["group"].astype(str).ne("").any()
    if by_group:
        names = sorted(set(table["group"].astype(str)))
        tab10 = colormaps["tab10"]
        for i, n in enumerate(names):
            m = (table["group"].astype(str) == n).to_numpy()
            ax.scatter(coords[m, 0], coords[m, 1], s=28, color=tab10(i % 10),
                       label=n or "(no group)")
        ax.legend(fontsize=8)
    elif table["frame"].nunique() > 1:
        sc = ax.scatter(coords[:, 0], coords[:, 1], c=table["frame"], cmap="viridis", s=28)
        fig.colorbar(sc, ax=ax, label="frame")
    else:  # one frame: a colour scale would say nothing
        ax.scatter(coords[:, 0], coords[:, 1], s=28, color="tab:blue")
    # objects cut by the border or folded by the map are often the outliers: ring them (holes
    # are filled before measuring and do not change the shape, so they are not ringed)
    flagged = np.zeros(len(table), bool)
    if "touches_border" in table.columns:
        flagged |= table["touches_border"].fillna(False).astype(bool).to_numpy()
    if "folded_fraction" in table.columns:
        flagged |= (table["folded_fraction"].astype(float) > FOLDED_WARNING).to_numpy()
    if flagged.any():
        ax.scatter(coords[flagged, 0], coords[flagged, 1], s=110, facecolors="none",
                   edgecolors="tab:red", linewidths=1.2,
                   label=f"{int(flagged.sum())} touch the border or fold (see 'warnings')")
        ax.legend(fontsize=8)
    if len(table) <= 60:
        names = "l" + table["label"].astype(str)
        if table["frame"].nunique() > 1:
            names = "t" + table["frame"].astype(str) + "/" + names
        if "movie" in table.columns and table["movie"].nunique() > 1:
            names = table["movie"].astype(str) + "/" + names
        for (x, y), oid in zip(coords, names, strict=True):
            if np.isfinite(x):
                ax.annotate(oid, (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel("MDS 1")
    ax.set_ylabel("MDS 2")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(title or "PF-SDM distances, 2-D MDS")
    save_figure(fig, path, dpi=120)
    return Path(path)


def load_features(path: str | os.PathLike, *, allow_empty: bool = False) -> pd.DataFrame:
    """Read a features CSV and check it is a complete :func:`napari_pfsdm.measure` table.

    Refused, with a message that says what to do: a file that is not a CSV table (an image
    given by mistake), a table without ``frame``/``label`` or feature columns, a table whose
    options (the ``.csv.json`` sidecar, or the comment line of older tables) cannot be found,
    a table missing some feature columns, and (unless ``allow_empty``) a table with no rows.
    """
    try:
        table = read_table_csv(path)
    except ValueError as exc:
        raise ValueError(
            f"{exc}; give the table written by 'pfsdm measure' (e.g. pfsdm measure "
            "LABELS.tif -o features.csv, then use features.csv here)"
        ) from None
    need = {"frame", "label"}
    if not need <= set(table.columns):
        raise ValueError(
            f"{path} is not a PF-SDM feature table (it needs frame, label and shape_rXX_nYY "
            "columns); make one with: pfsdm measure LABELS -o features.csv"
        )
    check_feature_table(table, ["shape"], where=str(path))
    if len(table) == 0 and not allow_empty:
        raise ValueError(
            f"{path} holds no objects (0 rows): its labels had only background; measure "
            "labels that contain objects"
        )
    return table
