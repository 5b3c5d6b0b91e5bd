"""Small rasterised test shapes built from polygons (imported by the tests)."""

from __future__ import annotations

import numpy as np
from skimage.draw import polygon as fill_polygon


def raster(outline: np.ndarray, size: int = 256, *, angle: float = 0.0, scale: float = 1.0,
           mirror: bool = False, shift=(0.0, 0.0)) -> np.ndarray:
    """Rasterise a normalised outline (K, 2) (row, col) after a similarity transform."""
    pts = np.asarray(outline, float).copy()
    if mirror:
        pts[:, 1] *= -1
    c, s = np.cos(angle), np.sin(angle)
    pts = pts @ np.array([[c, -s], [s, c]]).T * scale * size * 0.3
    pts += np.array([size / 2, size / 2]) + np.asarray(shift)
    mask = np.zeros((size, size), bool)
    rr, cc = fill_polygon(pts[:, 0], pts[:, 1], mask.shape)
    mask[rr, cc] = True
    return mask


def _curve(radius_fn, n: int = 720) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = radius_fn(t)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


BASE_SHAPES = {
    "circle": _curve(lambda t: np.ones_like(t)),
    "elongated": _curve(lambda t: 1 / np.sqrt((np.cos(t) / 1.0) ** 2 + (np.sin(t) / 0.35) ** 2)),
    "folded": _curve(lambda t: 0.7 + 0.25 * np.cos(2 * t) + 0.15 * np.sin(3 * t + 0.5)),
    "rounded_square": _curve(
        lambda t: (np.abs(np.cos(t)) ** 6 + np.abs(np.sin(t)) ** 6) ** (-1 / 6)
    ),
    "branched": _curve(lambda t: 0.45 + 0.5 * np.clip(np.cos(3 * t), 0, None) ** 3),
}




def drifting_ellipses(n_frames: int = 3, n: int = 8, dtype=np.uint16, ids=None) -> np.ndarray:
    """A label movie (n_frames × 96 × 160) of ``n`` ellipses of two kinds (round, long)
    drifting right one pixel a frame, four to a row; ``ids`` their labels (default 1 … n),
    which follow them."""
    ids = list(range(1, n + 1)) if ids is None else ids
    yy, xx = np.mgrid[:96, :160]
    out = np.zeros((n_frames, 96, 160), dtype)
    for t in range(n_frames):
        for i, lab in enumerate(ids):
            cy, cx = 22 + 48 * (i // 4), 18 + 36 * (i % 4) + t
            a, b = (9, 9) if i % 2 else (13, 6)
            out[t][((yy - cy) / a) ** 2 + ((xx - cx) / b) ** 2 < 1] = lab
    return out
