"""Where the elastic term's nearest neighbours can come from: candidates and bounds, measured.

A search under D = D_PF + μ d_E that looks at few objects per query needs either candidates
that hold the query's k nearest under D, or a cheap lower bound of d_E that rules the other
objects out. This script measures both on full matrices (all pairs computed), in one run:

- **recall@10 of C candidates**: the share of each object's 10 nearest under D that are
  among its C nearest under a cheaper distance: D_PF alone (what
  :func:`napari_pfsdm.nearest_neighbours` uses), D_PF plus γ times the distance of vectors
  that do not change with the start point or a mirror image (the Fourier magnitudes of each
  signature channel, 8 lowest frequencies, and the channel's values sorted), and D_PF plus
  γ times the rigid signature distance (the least L2 distance over every cyclic start
  shift and the mirror, from the signatures' spectra); γ = f × the median of μ d_E over the
  distance, f ∈ {0.25, 0.5, 1};
- **lower bounds of d_E for an exact search**, their ratio to d_E:

  - *the range bound*: per row of one signature, the L1 distance of its values (and its
    midpoints) to the other signature's range, channel by channel (every path of the DTW
    visits every row; a start shift, a mirror image or a warp cannot bring a value inside
    the range), the larger of both directions;
  - *the envelope bound* (LB_Keogh's, made start- and mirror-invariant): per start shift s and
    orientation of the other signature, each row's L1 distance to the other's envelope around
    i + s (per channel its least and greatest value within the band ± 1 point: every cell of
    row i in the band of shift s, half-point matches included, lies inside it), summed over
    the rows; the least over all 2n shifts and orientations (d_E refines some of them), the
    larger of both directions. Tighter than the range bound for any one shift, but it must
    hold for every shift at once.

Objects: MPEG-7 (the cache of ``benchmarks/mpeg7_elastic.py``) and ``--blobs`` moving blobs
(as ``benchmarks/neighbours_elastic.py``). Run (repository root)::

    .venv/bin/python benchmarks/neighbours_elastic_candidates.py --blobs 3000
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from napari_pfsdm.core.elastic import BAND, _mirrored  # noqa: E402

K = 10


def mpeg7_data() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    import mpeg7
    import mpeg7_elastic

    masks, _, _, _ = mpeg7.load_masks(mpeg7.DEFAULT_FOLDER)
    f = mpeg7_elastic.features(masks, True)
    c = mpeg7_elastic.components(f, [(3.0, 5)], True)
    return f["sig"], c["D_PF"], c["D_E_t3_s5"]


def blob_data(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    import napari_pfsdm as pf
    import neighbours_elastic
    from napari_pfsdm.analysis.tables import signatures_from_table
    from napari_pfsdm.core.elastic import elastic_distance_matrix

    table = neighbours_elastic.blob_items(n, 0)
    sig = signatures_from_table(table)
    return sig, pf.distance_matrix(table), elastic_distance_matrix(sig)


def invariant_vectors(sig: np.ndarray) -> np.ndarray:
    """Per object: each channel's 8 lowest Fourier magnitudes and its sorted values, scaled so
    that their Euclidean distance is in the units of an RMS difference per point."""
    n = sig.shape[2]
    mag = np.abs(np.fft.rfft(sig, axis=-1))[:, :, :8] / n
    return np.hstack([mag.reshape(len(sig), -1),
                      np.sort(sig, axis=-1).reshape(len(sig), -1) / np.sqrt(n)])


def rigid_distance(sig: np.ndarray, chunk: int = 64) -> np.ndarray:
    """sqrt(min over cyclic shifts s and the mirror image of Σ‖a(i) − b(i + s)‖² / n)."""
    n = sig.shape[2]
    mirrored = np.roll(sig[..., ::-1], 1, axis=-1)  # the mirror image's signature
    spec = [np.fft.rfft(sig, axis=-1), np.fft.rfft(mirrored, axis=-1)]
    sq = (sig**2).sum(axis=(1, 2))
    out = np.empty((len(sig), len(sig)))
    for i0 in range(0, len(sig), chunk):
        a = np.conj(spec[0][i0:i0 + chunk])
        corr = np.max([np.fft.irfft(np.einsum("ich,jch->ijh", a, b), n=n, axis=-1).max(-1)
                       for b in spec], axis=0)
        out[i0:i0 + chunk] = np.sqrt(np.maximum(sq[i0:i0 + chunk, None] + sq - 2 * corr, 0) / n)
    return out


def range_bound(sig: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The range lower bound of d_E (module docstring) of ``rows`` against every object."""
    n = sig.shape[2]
    mid = 0.5 * (sig + np.roll(sig, -1, axis=-1))
    lo, hi = np.minimum(sig, mid), np.maximum(sig, mid)
    m, big = sig.min(axis=-1), sig.max(axis=-1)  # (objects, channels)

    out = np.empty((len(rows), len(sig)))
    for r, i in enumerate(rows):
        # row i's values outside each object's ranges, and each object's outside row i's
        ab = (np.maximum(0, lo[i][None] - big[:, :, None]).sum((1, 2))
              + np.maximum(0, m[:, :, None] - hi[i][None]).sum((1, 2)))
        ba = (np.maximum(0, lo - big[i][None, :, None]).sum((1, 2))
              + np.maximum(0, m[i][None, :, None] - hi).sum((1, 2)))
        out[r] = np.maximum(ab, ba) / n
    return out


def envelope_bound(sig: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                   band: int = BAND) -> np.ndarray:
    """The envelope lower bound of d_E (module docstring) of ``rows`` against ``cols``."""
    n = sig.shape[2]
    x = sig.astype(np.float32)
    mid = 0.5 * (x + np.roll(x, -1, axis=-1))
    lo, hi = x.copy(), x.copy()
    for d in range(1, band + 2):
        for r in (d, -d):
            np.minimum(lo, np.roll(x, r, axis=-1), out=lo)
            np.maximum(hi, np.roll(x, r, axis=-1), out=hi)
    shifts = np.arange(n)[:, None] + np.arange(n)[None, :]  # [s, i] → i + s

    def every_shift(e: np.ndarray) -> np.ndarray:
        """(objects, 2n, C, n): e at i + s, for both orientations."""
        both = np.stack([e, _mirrored(e)], axis=1)  # (objects, 2, C, n)
        out = both[:, :, :, shifts % n]  # (objects, 2, C, s, i)
        return out.transpose(0, 1, 3, 2, 4).reshape(len(e), 2 * n, e.shape[1], n)

    def one_way(pts: np.ndarray, mids: np.ndarray, lo_s: np.ndarray,
                hi_s: np.ndarray) -> np.ndarray:
        # pts, mids: (..., 1, C, n) against lo_s, hi_s: (..., 2n, C, n)
        d0 = (np.maximum(lo_s - pts, 0) + np.maximum(pts - hi_s, 0)).sum(axis=-2)
        d2 = (np.maximum(lo_s - mids, 0) + np.maximum(mids - hi_s, 0)).sum(axis=-2)
        return np.minimum(d0, d2).sum(axis=-1).min(axis=-1) / n

    lo_c, hi_c = every_shift(lo[cols]), every_shift(hi[cols])
    out = np.empty((len(rows), len(cols)))
    for r, i in enumerate(rows):
        lo_r, hi_r = every_shift(lo[i:i + 1]), every_shift(hi[i:i + 1])
        ab = one_way(x[i][None, None], mid[i][None, None], lo_c, hi_c)
        ba = one_way(x[cols][:, None], mid[cols][:, None], lo_r, hi_r)
        out[r] = np.maximum(ab, ba)
    return out


def recall(full: np.ndarray, cheap: np.ndarray, n_cand: int) -> float:
    full, cheap = full.copy(), cheap.copy()
    np.fill_diagonal(full, np.inf)
    np.fill_diagonal(cheap, np.inf)
    truth = np.argsort(full, axis=1, kind="stable")[:, :K]
    cand = np.argpartition(cheap, n_cand, axis=1)[:, :n_cand]
    return float(np.mean([len(set(t) & set(c)) / K for t, c in zip(truth, cand, strict=True)]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--blobs", type=int, default=3000)
    ap.add_argument("--candidates", type=int, nargs="+", default=[20, 40, 80, 120])
    ap.add_argument("--bound-rows", type=int, default=100)
    ap.add_argument("--envelope-pairs", type=int, nargs=2, default=[30, 300],
                    metavar=("ROWS", "COLUMNS"),
                    help="the envelope bound on the first ROWS of the range bound's rows "
                         "against COLUMNS random objects")
    args = ap.parse_args(argv)
    from scipy.spatial.distance import cdist

    from napari_pfsdm.core.distances import RECOMMENDED_ELASTIC_WEIGHT

    mu = RECOMMENDED_ELASTIC_WEIGHT
    cols = " | ".join(f"C = {c}" for c in args.candidates)
    print(f"| objects | candidates from | {cols} |\n|---|---|"
          + "---|" * len(args.candidates))
    bounds = {}
    for name, (sig, d_pf, d_e) in (("MPEG-7", mpeg7_data()),
                                   (f"{args.blobs:,} blobs", blob_data(args.blobs))):
        full = d_pf + mu * d_e
        off = ~np.eye(len(sig), dtype=bool)
        cheap = {"D_PF": d_pf}
        for label, g in (("invariant vectors", cdist(*(2 * [invariant_vectors(sig)]))),
                         ("rigid signature distance", rigid_distance(sig))):
            gamma = np.median(mu * d_e[off] / np.maximum(g[off], 1e-12))
            for fac in (0.25, 0.5, 1.0):
                cheap[f"D_PF + {fac:g} γ × {label}"] = d_pf + fac * gamma * g
        for label, c in cheap.items():
            vals = " | ".join(f"{recall(full, c, nc):.4f}" for nc in args.candidates)
            print(f"| {name} | {label} | {vals} |", flush=True)
        rows = np.random.default_rng(0).choice(len(sig), args.bound_rows, replace=False)
        lb = range_bound(sig, rows)
        sub = d_e[rows]
        ok = off[rows]
        assert (lb[ok] <= sub[ok] * (1 + 1e-4) + 1e-6).all(), "the bound exceeds d_E"
        bounds[name, "range bound"] = lb[ok] / np.maximum(sub[ok], 1e-12)
        er = rows[:args.envelope_pairs[0]]
        ec = np.random.default_rng(1).choice(len(sig), args.envelope_pairs[1], replace=False)
        lb = envelope_bound(sig, er, ec)
        sub = d_e[np.ix_(er, ec)]
        ok = er[:, None] != ec[None, :]
        assert (lb[ok] <= sub[ok] * (1 + 1e-4) + 1e-6).all(), "the bound exceeds d_E"
        bounds[name, "envelope bound"] = lb[ok] / np.maximum(sub[ok], 1e-12)
    print("\n| objects | bound | pairs | bound / d_E: median | 90th percentile | share > 0.5 |\n"
          "|---|---|---|---|---|---|")
    for (name, kind), ratio in bounds.items():
        print(f"| {name} | {kind} | {ratio.size:,} | {np.median(ratio):.3f} | "
              f"{np.percentile(ratio, 90):.3f} | {np.mean(ratio > 0.5):.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
