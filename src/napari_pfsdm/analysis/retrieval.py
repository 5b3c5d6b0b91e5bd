"""Retrieval scores for a distance matrix: bull's-eye and leave-one-out 1-NN.

Pure functions over a square distance matrix ``D`` (smaller = more similar) and one label per
row. They are the scores of the MPEG-7 CE-Shape-1 shape-retrieval benchmark
(``benchmarks/mpeg7.py``) but work for any labelled collection.

Ties are broken by index (a stable sort), NaN distances count as infinitely far, and the query
itself is always ranked first by the bull's-eye score (it is "included", as the benchmark
defines it) and never returned by the 1-NN score (it is "left out").
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError

__all__ = ["Bullseye", "bullseye", "loo_1nn", "loo_1nn_fraction", "nearest"]


class Bullseye(NamedTuple):
    """Result of :func:`bullseye`.

    Attributes
    ----------
    score : float
        The bull's-eye score in percent: the mean over all queries of
        (same-class items among the ``k`` nearest, the query included) / (class size).
    per_class : dict of str to float
        The same mean restricted to the queries of each class, in percent, keyed by
        ``str(label)`` in sorted label order.
    per_query : numpy.ndarray
        (n,) the ratio of each query, in percent.
    """

    score: float
    per_class: dict[str, float]
    per_query: np.ndarray


def _check(D: np.ndarray, labels) -> tuple[np.ndarray, np.ndarray]:
    D = np.asarray(D, dtype=float)
    labels = np.asarray(labels)
    if D.ndim != 2 or D.shape[0] != D.shape[1]:
        raise InputError(
            f"The distance matrix must be square (n, n); got shape {D.shape}. "
            "Pass the full pairwise matrix, not a condensed vector."
        )
    if labels.ndim != 1 or labels.shape[0] != D.shape[0]:
        n_labels = labels.shape[0] if labels.ndim else 0
        raise InputError(
            f"Give one label per row of the distance matrix: got {n_labels} labels for "
            f"{D.shape[0]} rows."
        )
    D = np.where(np.isnan(D), np.inf, D)
    return D, labels


def _ranking(D: np.ndarray, *, include_self: bool) -> np.ndarray:
    """(n, n) indices of each row sorted nearest first; self first or removed (last)."""
    n = D.shape[0]
    work = D.copy()
    diag = np.arange(n)
    work[diag, diag] = -np.inf if include_self else np.inf
    order = np.argsort(work, axis=1, kind="stable")
    if not include_self:
        # the query sits among the +inf entries; move it to the very end of its row
        keep = order != diag[:, None]
        order = np.concatenate([order[keep].reshape(n, n - 1), diag[:, None]], axis=1)
    return order


def nearest(D: np.ndarray, query: int, k: int, *, include_self: bool = False) -> np.ndarray:
    """Indices of the ``k`` items nearest to ``query``, nearest first.

    Parameters
    ----------
    D : (n, n) array
        Distance matrix.
    query : int
        Row of the query.
    k : int
        How many neighbours to return.
    include_self : bool
        If True the query itself is returned first.

    Returns
    -------
    numpy.ndarray
        (min(k, n),) integer indices (ties broken by index).
    """
    D = np.asarray(D, dtype=float)
    row = np.where(np.isnan(D[query]), np.inf, D[query]).copy()
    row[query] = -np.inf if include_self else np.inf
    order = np.argsort(row, kind="stable")
    if not include_self:
        order = order[order != query]
    return order[:k]


def bullseye(D: np.ndarray, labels, k: int = 40) -> Bullseye:
    """Bull's-eye retrieval score of a distance matrix.

    For every query, keep the ``k`` items nearest to it, the query itself included, count those
    of the query's class and divide by the size of that class (20 on MPEG-7, where ``k = 40``
    is twice the class size). The score is the mean ratio over all queries, in percent.

    Parameters
    ----------
    D : (n, n) array
        Distances (NaN = infinitely far). Need not be symmetric: row ``i`` ranks for query ``i``.
    labels : (n,) array-like
        Class of each row.
    k : int
        Number of nearest items kept (40 on MPEG-7).

    Returns
    -------
    Bullseye
        ``score`` (percent), ``per_class`` (percent per class), ``per_query`` (percent).

    Examples
    --------
    >>> D = np.array([[0, 1, 5, 5], [1, 0, 5, 5], [5, 5, 0, 1], [5, 5, 1, 0]])
    >>> bullseye(D, ["a", "a", "b", "b"], k=2).score
    100.0
    """
    D, labels = _check(D, labels)
    if k < 1:
        raise InputError(f"k must be at least 1 (the number of nearest items kept); got {k}.")
    n = D.shape[0]
    order = _ranking(D, include_self=True)[:, : min(k, n)]
    same = labels[order] == labels[:, None]
    classes, inverse, counts = np.unique(labels, return_inverse=True, return_counts=True)
    per_query = 100.0 * same.sum(axis=1) / counts[inverse]
    per_class = {
        str(c): float(per_query[inverse == j].mean()) for j, c in enumerate(classes)
    }
    return Bullseye(float(per_query.mean()), per_class, per_query)


def loo_1nn(D: np.ndarray, labels) -> float:
    """Leave-one-out nearest-neighbour accuracy, in percent (:func:`loo_1nn_fraction` × 100)."""
    return float(100.0 * loo_1nn_fraction(D, labels))


def loo_1nn_fraction(D: np.ndarray, labels) -> float:
    """Leave-one-out nearest-neighbour accuracy, as a fraction: the one 1-NN of the package.

    Each item is classified by the label of its nearest other item (itself excluded; ties
    broken by index). A query with no finite distance to any other item counts as a miss.

    Parameters
    ----------
    D : (n, n) array
        Distances (NaN = infinitely far).
    labels : (n,) array-like
        Class of each row.

    Returns
    -------
    float
        Fraction of items whose nearest other item has the same label.

    Examples
    --------
    >>> d = np.array([[0, 1, 5], [1, 0, 4], [5, 4, 0.0]])
    >>> loo_1nn_fraction(d, np.array([0, 0, 1]))
    0.6666666666666666
    """
    D, labels = _check(D, labels)
    if D.shape[0] < 2:
        raise InputError("Leave-one-out 1-NN needs at least two items.")
    work = D.copy()
    np.fill_diagonal(work, np.inf)
    nn = np.argmin(work, axis=1)
    found = np.isfinite(work[np.arange(work.shape[0]), nn])  # a row of NaN finds nothing
    return float(np.mean(found & (labels[nn] == labels)))
