"""Pixel-space baselines for the axis-number prediction: learn from the images themselves.

The paper compares PF-SDM features against a CNN trained on the segmentation and the raw
reporter images. This module gives two such baselines, both as ``fit_predict`` callables for
:func:`napari_pfsdm.analysis.classification.evaluate` (same splits, same late fusion):

* :func:`sklearn_pixel_model` (always available): standardised downsampled pixels of the chosen
  frames, logistic regression with balanced class weights, the training set augmented by random
  rotations and reflections;
* :func:`cnn_model` (needs the optional ``torch``, ``pip install napari-pfsdm[cnn]``): a small
  CNN per channel (frames as input channels), trained with on-the-fly random rotations and
  reflections (plus noise for the intensity) and a class-balanced loss.

Both see each movie through :func:`pixel_stacks`: a square window centred on the object's
centroid (over the chosen frames; a careful user would centre, the rotation is left to the
augmentation), downsampled to ``size`` x ``size``, the intensity divided by the movie's 99th
percentile.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import ndimage as ndi
from skimage.transform import resize
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from napari_pfsdm.analysis.classification import FitPredict, parse_frames
from napari_pfsdm.errors import InputError

__all__ = ["augment", "cnn_model", "pixel_stacks", "sklearn_pixel_model", "torch_available"]


def torch_available() -> bool:
    """True when ``torch`` can be imported (the optional ``cnn`` extra)."""
    try:
        import torch  # noqa: F401
    except ImportError:
        return False
    return True


def pixel_stacks(
    labels: np.ndarray,
    intensity: np.ndarray,
    frames: Sequence[int] | str | None = None,
    size: int = 32,
) -> tuple[np.ndarray, np.ndarray]:
    """Centred, downsampled segmentation and intensity stacks of one-object movies.

    Parameters
    ----------
    labels, intensity : ndarray, (n_objects, T, Y, X)
        One-object movies (label > 0 is the object).
    frames : sequence of int or str, optional
        Frames to keep (default all).
    size : int
        Side of the downsampled images.

    Returns
    -------
    seg, img : ndarray, float32, (n_objects, n_frames, size, size)
        The mask (as area fractions in [0, 1]) and the normalised intensity.
    """
    if labels.ndim != 4 or intensity.shape != labels.shape:
        raise InputError(
            "labels and intensity must both be (n_objects, T, Y, X) one-object movies of the "
            f"same shape; got {labels.shape} and {intensity.shape}."
        )
    sel = parse_frames(frames, labels.shape[1])
    n, _, ny, nx = labels.shape
    win = min(ny, nx)
    seg = np.zeros((n, len(sel), size, size), dtype=np.float32)
    img = np.zeros_like(seg)
    for i in range(n):
        m = labels[i][sel] > 0
        s = intensity[i][sel].astype(np.float32)
        if not m.any():
            raise InputError(f"object {i} is empty in the chosen frames; drop it first.")
        cy, cx = ndi.center_of_mass(m.any(axis=0))
        y0, x0 = int(round(cy)) - win // 2, int(round(cx)) - win // 2
        pad = ((0, 0), (win, win), (win, win))
        bg = float(np.median(s[:, ~m.any(axis=0)])) if (~m.any(axis=0)).any() else 0.0
        mp = np.pad(m.astype(np.float32), pad)
        sp = np.pad(s, pad, constant_values=bg)
        box = np.s_[:, y0 + win : y0 + 2 * win, x0 + win : x0 + 2 * win]
        seg[i] = resize(mp[box], (len(sel), size, size), order=1, anti_aliasing=True)
        crop = resize(sp[box], (len(sel), size, size), order=1, anti_aliasing=True)
        img[i] = crop / max(float(np.percentile(crop, 99)), 1e-6)
    return seg, img


def augment(x: np.ndarray, n_copies: int, rng: np.random.Generator) -> np.ndarray:
    """The stack plus ``n_copies`` randomly rotated (any angle) and reflected copies.

    Parameters
    ----------
    x : ndarray, (n, ..., size, size)
        One sample per row; every image of a sample gets the same transform.
    n_copies : int
        Augmented copies per sample.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, ((1 + n_copies) * n, ..., size, size)
        The originals first, then the copies (copy-major: sample order repeats).
    """
    out = [x]
    for _ in range(n_copies):
        copy = np.empty_like(x)
        for i in range(len(x)):
            a = rng.uniform(0.0, 360.0)
            r = ndi.rotate(x[i], a, axes=(-2, -1), reshape=False, order=1, mode="nearest")
            copy[i] = r[..., ::-1] if rng.random() < 0.5 else r
        out.append(copy)
    return np.concatenate(out)


def sklearn_pixel_model(
    seg: np.ndarray,
    img: np.ndarray,
    y: np.ndarray,
    *,
    n_augment: int = 8,
    C: float = 0.01,
    seed: int = 0,
) -> FitPredict:
    """Logistic regression on downsampled pixels, per channel, with augmentation.

    Parameters
    ----------
    seg, img : ndarray, (n_objects, F, s, s)
        From :func:`pixel_stacks`.
    y : ndarray, (n_objects,)
        Classes; only the training objects' labels are read.
    n_augment : int
        Rotated/reflected copies of every training sample.
    C : float
        Inverse L2 regularisation strength.
    seed : int
        Seed of the augmentation.

    Returns
    -------
    callable
        ``fit_predict(train_idx, predict_idx) -> (p_segmentation, p_intensity)``.
    """
    y = np.asarray(y).astype(int)
    rng = np.random.default_rng(seed)

    def _fit(x: np.ndarray, tr: np.ndarray, pr: np.ndarray) -> np.ndarray:
        xa = augment(x[tr], n_augment, rng).reshape((1 + n_augment) * len(tr), -1)
        ya = np.tile(y[tr], 1 + n_augment)
        clf = make_pipeline(
            StandardScaler(),
            LogisticRegression(
                C=C, class_weight="balanced", solver="liblinear", max_iter=1000, random_state=0
            ),
        )
        clf.fit(xa, ya)
        return clf.predict_proba(x[pr].reshape(len(pr), -1))[:, 1]

    def fit_predict(train_idx: np.ndarray, predict_idx: np.ndarray):
        return _fit(seg, train_idx, predict_idx), _fit(img, train_idx, predict_idx)

    return fit_predict


def cnn_model(
    seg: np.ndarray,
    img: np.ndarray,
    y: np.ndarray,
    *,
    epochs: int = 60,
    batch_size: int = 16,
    lr: float = 3e-3,
    width: int = 16,
    threads: int = 1,
    seed: int = 0,
) -> FitPredict:
    """A small CNN per channel (needs ``torch``), as the paper's pixel-space baseline.

    Three 3x3 conv blocks (``width``, 2 ``width``, 2 ``width`` filters, batch norm, max pool),
    global average pooling, dropout, one logit. The frames of a movie are the input channels.
    Adam, weighted binary cross-entropy (positive weight = negatives / positives), random
    rotations (any angle) and reflections every batch, plus Gaussian noise (std 0.05) and a
    random gain (0.8-1.2) for the intensity channel.

    Returns
    -------
    callable
        ``fit_predict(train_idx, predict_idx) -> (p_segmentation, p_intensity)``.
    """
    try:
        import torch
        from torch import nn
        from torch.nn import functional as F
    except ImportError:
        raise InputError(
            "the CNN baseline needs PyTorch; install it with `pip install napari-pfsdm[cnn]` "
            "(or `pip install torch`), or run the scikit-learn pixel baseline only."
        ) from None

    y = np.asarray(y).astype(np.float32)
    n_frames = seg.shape[1]

    def _net() -> nn.Module:
        w = width
        return nn.Sequential(
            nn.Conv2d(n_frames, w, 3, padding=1), nn.BatchNorm2d(w), nn.ReLU(), nn.MaxPool2d(2),
            nn.Conv2d(w, 2 * w, 3, padding=1), nn.BatchNorm2d(2 * w), nn.ReLU(), nn.MaxPool2d(2),
            nn.Conv2d(2 * w, 2 * w, 3, padding=1), nn.BatchNorm2d(2 * w), nn.ReLU(),
            nn.AdaptiveAvgPool2d(1), nn.Flatten(), nn.Dropout(0.3), nn.Linear(2 * w, 1),
        )

    def _augment(xb: torch.Tensor, gen: torch.Generator, noisy: bool) -> torch.Tensor:
        n = xb.shape[0]
        theta = torch.rand(n, generator=gen) * 2 * np.pi
        flip = torch.where(torch.rand(n, generator=gen) < 0.5, -1.0, 1.0)
        cos, sin = torch.cos(theta), torch.sin(theta)
        mat = torch.stack(
            [torch.stack([cos * flip, -sin, torch.zeros(n)], 1),
             torch.stack([sin * flip, cos, torch.zeros(n)], 1)], 1
        )
        grid = F.affine_grid(mat, list(xb.shape), align_corners=False)
        out = F.grid_sample(xb, grid, mode="bilinear", padding_mode="border", align_corners=False)
        if noisy:
            gain = 0.8 + 0.4 * torch.rand(n, 1, 1, 1, generator=gen)
            out = out * gain + 0.05 * torch.randn(out.shape, generator=gen)
        return out

    def _fit(x: np.ndarray, tr: np.ndarray, pr: np.ndarray, noisy: bool) -> np.ndarray:
        torch.set_num_threads(threads)
        torch.manual_seed(seed)
        gen = torch.Generator().manual_seed(seed)
        net = _net()
        opt = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=1e-4)
        xt = torch.from_numpy(np.ascontiguousarray(x[tr]))
        yt = torch.from_numpy(y[tr])
        n_pos = float(yt.sum())
        pos_weight = torch.tensor([(len(tr) - n_pos) / max(n_pos, 1.0)])
        loss_fn = nn.BCEWithLogitsLoss(pos_weight=pos_weight)
        net.train()
        for _ in range(epochs):
            order = torch.randperm(len(tr), generator=gen)
            for start in range(0, len(tr), batch_size):
                idx = order[start : start + batch_size]
                if len(idx) < 2:  # batch norm needs two samples
                    continue
                opt.zero_grad()
                loss = loss_fn(net(_augment(xt[idx], gen, noisy)).squeeze(1), yt[idx])
                loss.backward()
                opt.step()
        net.eval()
        with torch.no_grad():
            logits = net(torch.from_numpy(np.ascontiguousarray(x[pr]))).squeeze(1)
        return torch.sigmoid(logits).numpy().astype(np.float64)

    def fit_predict(train_idx: np.ndarray, predict_idx: np.ndarray):
        return _fit(seg, train_idx, predict_idx, False), _fit(img, train_idx, predict_idx, True)

    return fit_predict
