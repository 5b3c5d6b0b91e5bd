"""A synthetic growth study with known answers: organoids of several groups, one per movie,
on uneven days (one day imaged twice), seen on two microscopes of different pixel sizes.

Each group grows at its own rate (its areas drift apart over the days) and has its own
elongation (its shape differs from the start); every organoid has its own size and a bumpy
outline. The same organoids are drawn for each microscope at that microscope's pixel size, so
that their physical areas agree and their pixel areas do not. What the tutorial
(docs/tutorial.md) does to the public brain-organoid study, its test does to this one.

Examples
--------
>>> s = make_study(per_group=2, seed=0)
>>> sorted(s.labs), s.days[3:6], sorted(s.groups["group"].value_counts().items())
(['LabA', 'LabB'], (10.0, 12.0, 12.0), [('A', 2), ('B', 2), ('C', 2), ('wt', 2)])
>>> s.movies["LabA"]["org01"].shape, s.movies["LabB"]["org01"].shape
((11, 128, 128), (11, 135, 135))
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = ["GROWTH", "Study", "make_study"]

#: Each group's growth (µm² per day) and elongation (minor / major axis).
GROWTH = {"wt": (900.0, 0.95), "A": (900.0, 0.7), "B": (1800.0, 0.95), "C": (2700.0, 0.8)}


@dataclass
class Study:
    """What :func:`make_study` drew.

    Attributes
    ----------
    movies : dict
        Microscope → movie name → (T, Y, X) uint8 labels (1 = the organoid).
    labs : dict
        Microscope → pixel size (µm).
    days : tuple of float
        Each frame's culture day (uneven; one day twice).
    groups : DataFrame
        ``movie`` (as a lab writes it: ``org01.tif``) and ``group``.
    areas : DataFrame
        ``movie``, ``frame``, ``area_um2``: each organoid's true area (µm²) at each frame.
    """

    movies: dict
    labs: dict
    days: tuple
    groups: pd.DataFrame
    areas: pd.DataFrame


def _outline_mask(size: int, pixel: float, area: float, aspect: float, turn: float,
                  bumps: np.ndarray) -> np.ndarray:
    """An organoid of ``area`` µm² drawn at ``pixel`` µm per pixel: an ellipse of ``aspect``,
    turned by ``turn``, its radius modulated by ``bumps`` (small harmonics)."""
    a = np.sqrt(area / (np.pi * aspect)) / pixel
    b = aspect * a
    yy, xx = np.mgrid[:size, :size] - (size - 1) / 2
    u = xx * np.cos(turn) + yy * np.sin(turn)
    v = -xx * np.sin(turn) + yy * np.cos(turn)
    theta = np.arctan2(v / b, u / a)
    rho = np.hypot(u / a, v / b)
    k = np.arange(2, 2 + len(bumps))
    edge = 1 + (bumps[:, None, None] * np.cos(k[:, None, None] * theta)).sum(axis=0)
    return rho <= edge


def make_study(per_group: int = 4, *, days=(2, 5, 8, 10, 12, 12, 16, 19, 22, 25, 30),
               seed: int = 0,
               labs: dict | None = None, size_um: float = 405.0) -> Study:
    """The study (module docstring): ``per_group`` organoids of each group of
    :data:`GROWTH` on ``days``, drawn on each microscope of ``labs`` (name → pixel size in
    µm; default LabA 3.165, LabB 2.994) in a field of ``size_um`` µm."""
    labs = dict(labs or {"LabA": 3.165, "LabB": 2.994})
    days = tuple(float(d) for d in days)
    rng = np.random.default_rng(seed)
    movies: dict = {lab: {} for lab in labs}
    rows, areas = [], []
    k = 0
    for group, (rate, aspect) in GROWTH.items():
        for _ in range(per_group):
            k += 1
            name = f"org{k:02d}"
            start = rng.uniform(5000, 7000)
            turn = rng.uniform(0, np.pi)
            bumps = rng.normal(0, 0.025, 4)
            true = [start + rate * (d - days[0]) * rng.uniform(0.9, 1.1) for d in days]
            for lab, pixel in labs.items():
                size = int(round(size_um / pixel))
                movies[lab][name] = np.stack([
                    _outline_mask(size, pixel, area, aspect, turn, bumps).astype(np.uint8)
                    for area in true])
            rows.append({"movie": f"{name}.tif", "group": group})
            areas += [{"movie": name, "frame": t, "area_um2": a} for t, a in enumerate(true)]
    return Study(movies, labs, days, pd.DataFrame(rows), pd.DataFrame(areas))
