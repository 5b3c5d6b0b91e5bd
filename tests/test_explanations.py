"""The words of the generated explanations (napari_pfsdm.analysis.interpretation): a PC that
is a classic measure, up to sign, is said to follow it, with the direction in words that
follow from the measure's definition (a higher circularity 4πA/P² is rounder, a higher
minor/major axis ratio less elongated, a higher solidity less indented) and the side of the
axis where the higher values lie. The PCs here are the measures themselves (r = ±1 by
construction) or a hand-computed r."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from napari_pfsdm.analysis.interpretation import explain_components

IDS = {"frame": 0, "label": [1, 2, 3, 4]}


def explain(pc, **measures):
    s = pd.DataFrame({**IDS, "PC1": np.asarray(pc, float)})
    return explain_components(s, pd.DataFrame({**IDS, **measures}), n=1)[0]


@pytest.mark.parametrize("measure, name, higher", [
    ("circularity", "circularity (4πA/P²)", "rounder"),
    ("aspect_ratio", "minor/major axis ratio", "less elongated"),
    ("solidity", "solidity (area / convex hull)", "less indented"),
])
def test_the_words_follow_the_measures_definition_and_sign(measure, name, higher):
    """PC1 = the measure: its higher values (the higher side of the measure) to the right;
    PC1 = −measure: to the left, and still "follows" (|r| = 1)."""
    values = [0.2, 0.4, 0.6, 0.8]
    assert explain(values, **{measure: values}) == \
        f"PC1 follows {name}, r = +1.00: {higher} to the right"
    assert explain([-v for v in values], **{measure: values}) == \
        f"PC1 follows {name}, r = -1.00: {higher} to the left"


def test_the_strongest_correlation_wins_whatever_its_sign():
    """PC1 = −solidity (r = −1); circularity (0.4, 0.5, 0.2, 0.3) has r = +0.6 with PC1 (by
    hand: deviations ∓1.5, ∓0.5 against 0.05, 0.15, −0.15, −0.05: 0.3 / √(5 · 0.05)). The
    explanation names solidity, on the left."""
    pc = [-0.5, -0.6, -0.7, -0.8]
    circ = [0.4, 0.5, 0.2, 0.3]
    assert np.corrcoef(pc, circ)[0, 1] == pytest.approx(0.6)
    assert explain(pc, circularity=circ, solidity=[0.5, 0.6, 0.7, 0.8]) == \
        "PC1 follows solidity (area / convex hull), r = -1.00: less indented to the left"


def test_three_objects_are_enough_for_a_correlation():
    s = pd.DataFrame({"frame": 0, "label": [1, 2, 3], "PC1": [3.0, 1.0, 2.0]})
    m = pd.DataFrame({"frame": 0, "label": [1, 2, 3], "circularity": [0.9, 0.5, 0.7]})
    assert explain_components(s, m, n=1) == [
        "PC1 follows circularity (4πA/P²), r = +1.00: rounder to the right"]


def test_correlations_leave_out_each_pairs_missing_rows_and_match_by_key():
    """r of every PC with every measure over the rows where both are finite, the rows matched
    on (frame, label) whatever their order: pandas' pairwise-complete Pearson r (computed on
    the merged table) is the reference; fewer than three rows, or a constant, give NaN."""
    from napari_pfsdm.analysis.interpretation import component_correlations

    rng = np.random.default_rng(3)
    n = 40
    keys = {"frame": np.repeat([0, 1], n // 2), "label": np.tile(np.arange(1, n // 2 + 1), 2)}
    scores = pd.DataFrame({**keys, "PC1": rng.normal(size=n), "PC2": rng.normal(size=n)})
    scores.loc[[3, 7], "PC2"] = np.nan
    measures = pd.DataFrame({**keys, "circularity": rng.normal(size=n),
                             "aspect_ratio": rng.normal(size=n), "solidity": 0.9})
    measures.loc[[5, 7, 11], "aspect_ratio"] = np.nan
    measures = measures.iloc[rng.permutation(n)[: n - 4]]  # shuffled, four rows missing
    got = component_correlations(scores, measures)
    both = scores.merge(measures, on=["frame", "label"])
    for pc in ("PC1", "PC2"):
        for m in ("circularity", "aspect_ratio"):
            assert got.loc[pc, m] == pytest.approx(both[pc].corr(both[m]), abs=1e-12)
        assert np.isnan(got.loc[pc, "solidity"])  # constant
    few = component_correlations(scores.iloc[:2], measures)
    assert few.isna().all().all()


def test_the_librarys_pca_table_is_explained_as_its_columns_say():
    """``pca_scores`` names its columns ``shape_PC1`` …: their sentences are those of the same
    numbers under ``PC1`` … (this returned no sentence when only ``PC1`` was read), and an
    ``intensity_PC1`` column is read the same way."""
    import napari_pfsdm as pf
    from napari_pfsdm.analysis.interpretation import table_measures
    from napari_pfsdm.analysis.reduction import pca_scores

    labels = np.zeros((1, 64, 256), int)
    for k in range(6):  # rectangles from square to long
        labels[0, 20:20 + 20 - 2 * k, 4 + 42 * k:4 + 42 * k + 20 + 3 * k] = k + 1
    table = pf.measure(labels)
    scores, ratios = pca_scores(table, "shape", 2)
    measures = table_measures(table)
    plain = scores.rename(columns={"shape_PC1": "PC1", "shape_PC2": "PC2"})
    want = explain_components(plain, measures, ratios)
    assert len(want) == 2 and want[0].startswith("PC1 (")
    assert explain_components(scores, measures, ratios) == want
    other = scores.rename(columns={"shape_PC1": "intensity_PC1", "shape_PC2": "intensity_PC2"})
    assert explain_components(other, measures, ratios) == want


def test_the_pc_sentence_matches_rows_by_movie_frame_and_label():
    """Two movies whose labels repeat: the PCs and the measures are matched row by row, not by
    frame and label alone (which would pair each row with the other movie's label 1 too)."""
    import numpy as np
    import pandas as pd

    from napari_pfsdm.analysis.interpretation import component_correlations, table_measures

    rng = np.random.default_rng(0)
    rows = []
    for movie in ("a", "b"):
        for label in range(1, 11):
            c = rng.uniform(0.3, 0.95)
            rows.append({"movie": movie, "frame": 0, "label": label, "circularity": c,
                         "solidity": rng.uniform(0.8, 1), "axis_major_length": 10.0,
                         "axis_minor_length": 10.0 * rng.uniform(0.3, 1)})
    table = pd.DataFrame(rows)
    scores = table[["movie", "frame", "label"]].assign(PC1=2 * table["circularity"])
    shuffled = table.sample(frac=1, random_state=1).reset_index(drop=True)
    r = component_correlations(scores, table_measures(shuffled))
    assert r.loc["PC1", "circularity"] == pytest.approx(1.0)
