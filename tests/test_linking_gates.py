"""The gates of the linking, on hand-made cases whose answer is worked out by hand: the
default centroid linking's distance (2 median radii), its one-to-one assignment, the
overlap linking's min_iou and its gap closing, the jump measured in object radii, and a
Tracks layer naming objects (napari_pfsdm.analysis.tracking). Each test names the one-line
bug it catches (scripts/curated_mutants.py)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from napari_pfsdm.analysis import tracking as tk
from napari_pfsdm.core.table_schema import NO_TRACK, TRACK_COLUMN


def objects(rows, radius=5.0):
    """A table of (frame, label, y, x) rows, every object a disk of ``radius``."""
    f, lab, y, x = (np.array(c) for c in zip(*rows, strict=True))
    return pd.DataFrame({"frame": f, "label": lab, "area": np.pi * radius**2,
                         "centroid_y": y.astype(float), "centroid_x": x.astype(float)})


def test_centroid_linking_links_within_two_median_radii_only():
    """Radius 5 (area 25π): the default gate is 2 × 5 = 10 px. A step of 9 px continues the
    track, a step of 11 px starts a new one. Mutants: the gate dropped after the assignment,
    the gate of one radius (9 px refused), the radius without its 1/π (√(25π) = 8.9: 11 px
    accepted)."""
    t = objects([(0, 1, 0, 0), (1, 1, 9, 0), (0, 2, 100, 0), (1, 2, 111, 0)])
    tr = tk.link_centroids(t)
    assert tr[0] == tr[1]  # 9 px ≤ 10
    assert tr[2] != tr[3]  # 11 px > 10
    assert len(set(tr.tolist())) == 3


def test_centroid_linking_assigns_under_the_gate():
    """Gate 10 px. P1 (0, 0) → Q1 (9.5, 0) is the one link within the gate; the pairing with
    the least total distance ignoring the gate is the crossed one (P1–Q2 11 + P2–Q1 10.5 =
    21.5 < 9.5 + 31), both beyond the gate: an assignment blind to the gate keeps no link."""
    t = objects([(0, 1, 0, 0), (0, 2, 20, 0), (1, 3, 9.5, 0), (1, 4, -11, 0)])
    tr = tk.link_centroids(t)
    assert tr[0] == tr[2]  # P1 → Q1
    assert len(set(tr.tolist())) == 3  # P2 and Q2 alone


def test_median_radius_counts_objects_with_an_area_only():
    """Rows with area 0 (or NaN) say nothing of the objects' size: the gate stays 2 × 5
    whatever their number. A median over six zeros and four disks (radius 0) would link
    nothing."""
    t = objects([(0, 1, 0, 0), (1, 1, 6, 0), (0, 2, 50, 0), (1, 2, 50, 6)])
    zero = objects([(0, 3 + k, 0, 0) for k in range(7)])
    zero["area"] = [0.0] * 6 + [np.nan]
    zero[["centroid_y", "centroid_x"]] = np.nan  # no centroid: no track
    tr = tk.link_centroids(pd.concat([t, zero], ignore_index=True))
    assert tr[0] == tr[1] and tr[2] == tr[3] and tr[0] != tr[2]
    assert (tr[4:] == NO_TRACK).all()


def test_jump_in_object_radii_uses_the_mean_area():
    """An object of radius 10 (area 100π) in both frames moving 5 px: half a radius. Taking
    the summed area's radius would give 5 / (10 √2)."""
    t = objects([(0, 1, 0, 0), (1, 1, 3, 4), (0, 2, 100, 0), (1, 2, 103, 4)], radius=10.0)
    check = tk.check_tracking(t)
    assert check.median_jump == pytest.approx(5.0)
    assert check.median_jump_radii == pytest.approx(0.5)
    assert check.tracked


def test_overlap_linking_never_links_objects_below_min_iou():
    """Frame 0: A (20 × 20 at columns 0–19), B (20 × 3 at columns 20–22). Frame 1: C (20 × 21
    at columns 2–22), D (20 × 2 at columns 0–1). IoU: A–C 360/460, A–D 40/400, B–C 60/420,
    B–D 0. The best matching pairs A–C and leaves B–D, which share no pixel: B's track ends,
    D starts one (an assignment that keeps its zero-gain pair links them)."""
    lab = np.zeros((2, 30, 30), np.uint16)
    lab[0, :20, 0:20] = 1  # A
    lab[0, :20, 20:23] = 2  # B
    lab[1, :20, 2:23] = 3  # C
    lab[1, :20, 0:2] = 4  # D
    out = tk.link_labels(lab, min_iou=0.05).set_index(["frame", "label"])[TRACK_COLUMN]
    assert out[(1, 3)] == out[(0, 1)]
    assert out[(1, 4)] not in (out[(0, 1)], out[(0, 2)])
    assert out.nunique() == 3


def test_overlap_gap_closing_leaves_linked_objects_alone():
    """A (frame 0) is missed in frame 1, where B appears beside it (no shared pixel); in frame
    2, C overlaps both where A was and where B is, and E is new. C continues B (its
    predecessor); gap closing may continue A only with a free object, and E does not overlap
    A: A's track ends."""
    lab = np.zeros((3, 40, 40), np.uint16)
    lab[0, :10, 0:10] = 1  # A
    lab[1, :10, 12:22] = 2  # B
    lab[2, :10, 6:16] = 3  # C: 4 columns of A, 4 of B
    lab[2, 30:40, 30:40] = 4  # E
    out = tk.link_labels(lab).set_index(["frame", "label"])[TRACK_COLUMN]
    assert out[(2, 3)] == out[(1, 2)]
    assert out[(0, 1)] != out[(1, 2)]
    assert out[(2, 4)] not in (out[(0, 1)], out[(1, 2)])


def test_tracks_layer_one_object_one_track_one_track_one_object():
    """Two objects of frame 0. Track 5 has two points in frame 0: on object 1's centroid and
    3 px off object 2's; it keeps the nearest (object 1). Track 6 also lands on object 1,
    1 px off: object 1 keeps track 5 (nearer), and track 6 names nothing else."""
    lab = np.zeros((1, 40, 40), np.uint16)
    lab[0, 0:11, 0:11] = 1  # centroid (5, 5)
    lab[0, 20:31, 20:31] = 2  # centroid (25, 25)
    table = objects([(0, 1, 5, 5), (0, 2, 25, 25)])
    tracks = np.array([[5, 0, 5, 5], [5, 0, 25, 28], [6, 0, 5, 6]], float)
    assert tk.track_ids_from_tracks(tracks, table, lab).tolist() == [5, NO_TRACK]
