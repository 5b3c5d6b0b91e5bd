"""The distances' small matrix products run on one BLAS thread, large ones on the machine's
(``core/threads.py``): what OpenBLAS reports while the functions that hold the products run.

The tests run in a Python process of their own (:func:`test_in_a_process_of_their_own`):
after a napari viewer's Run in the same process, OpenBLAS no longer takes a limit of its
threads from threadpoolctl at all (seen in the full suite), which says nothing of the
distances."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import ThreadpoolController, threadpool_limits

import napari_pfsdm as pf
from napari_pfsdm.core import boundary, distances, threads

#: The functions whose statements make the default and the aligned distances' products: every
#: numpy call they make runs while their products' BLAS setting holds.
HOLDERS = {"_sq_euclidean": distances, "_align_sq": distances, "_coarse_search": boundary,
           "_refine": boundary, "_corr": boundary}


def _blobs(n: int, seed: int = 0) -> list:
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:64, :64] - 31.5
    theta = np.arctan2(yy, xx)
    out = []
    for _ in range(n):
        r = 18 * (1 + sum(rng.uniform(0, 0.3 / k) * np.cos(k * theta + rng.uniform(0, 6))
                          for k in range(2, 6)))
        out.append(pf.pfsdm(np.hypot(yy * rng.uniform(1, 1.4), xx) < r))
    return out


@pytest.fixture(scope="module")
def objects():
    return _blobs(40)


#: Set in the process of their own, where the tests below run.
FRESH = "PFSDM_BLAS_TESTS_FRESH"
def test_in_a_process_of_their_own():
    if os.environ.get(FRESH):
        pytest.skip("this is the process of their own")
    run = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:xvfb", "-p",
                          "no:cacheprovider", "-q", "-rs", str(Path(__file__))],
                         env={**os.environ, FRESH: "1"}, capture_output=True, text=True,
                         cwd=Path(__file__).parent)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    if "this BLAS cannot run two threads" in run.stdout:
        pytest.skip("this BLAS cannot run two threads")
    assert "\n4 passed" in run.stdout, run.stdout[-1000:]


@pytest.fixture
def two_blas_threads():
    """The machine's default made two BLAS threads (as on any machine with two cores), or a
    skip when OpenBLAS cannot have them."""
    if not os.environ.get(FRESH):
        pytest.skip("run in a process of their own (test_in_a_process_of_their_own)")
    import scipy.linalg  # noqa: F401  (SciPy's OpenBLAS too)

    with threadpool_limits(2, user_api="blas"):
        if _blas_threads() != 2:
            pytest.skip("this BLAS cannot run two threads")
        yield


def _blas_threads() -> int:
    return max(lib.get_num_threads()
               for lib in ThreadpoolController().select(user_api="blas").lib_controllers)


def _threads_seen(run) -> dict[str, set[int]]:
    """The BLAS threads OpenBLAS reports at every call that the product holders
    (:data:`HOLDERS`) make while ``run()`` runs (numpy's functions, their own helpers), by
    holder."""
    libs = ThreadpoolController().select(user_api="blas").lib_controllers
    codes = {}
    for name, module in HOLDERS.items():
        if hasattr(module, name):
            fn = getattr(module, name)
            codes[getattr(fn, "__wrapped__", fn).__code__] = name
    seen: dict[str, set[int]] = {}

    def hook(frame, event, arg):
        caller = frame if event == "c_call" else frame.f_back if event == "call" else None
        if caller is not None and caller.f_code in codes:
            seen.setdefault(codes[caller.f_code], set()).add(
                max(lib.get_num_threads() for lib in libs))

    sys.setprofile(hook)
    try:
        run()
    finally:
        sys.setprofile(None)
    return seen


def test_small_products_run_on_one_blas_thread(objects, two_blas_threads):
    seen = _threads_seen(lambda: (pf.distance_matrix(objects),
                                  pf.distance_matrix(objects, invariance="combined")))
    assert seen and all(counts == {1} for counts in seen.values()), seen
    assert set(seen) == set(HOLDERS)  # every product was watched
    assert _blas_threads() == 2  # the machine's setting is back after them


def test_large_products_keep_the_machines_threads(objects, two_blas_threads, monkeypatch):
    # the 40 objects' Gram matrix (2 · 40 · 176 · 40 = 563,200 operations) counts as large,
    # the boundary term's per-shift products (8 · 40 · 32 · 40 = 409,600) and its refinement
    # (8 · 32 · 780 = 199,680) as small: each product is judged by its own size
    monkeypatch.setattr(threads, "SMALL_PRODUCT", 5e5)
    seen = _threads_seen(lambda: pf.distance_matrix(objects))
    assert seen == {"_sq_euclidean": {2}, "_coarse_search": {1}, "_refine": {1}, "_corr": {1}}
    monkeypatch.setattr(threads, "SMALL_PRODUCT", 0.0)  # every product large
    seen = _threads_seen(lambda: pf.distance_matrix(objects, invariance="combined"))
    assert seen == {name: {2} for name in HOLDERS}


def test_the_distances_do_not_depend_on_the_machines_blas_threads(two_blas_threads):
    # a product split over two threads sums in another order: its last bits would move
    objects = _blobs(150, seed=1)
    d_default = pf.distance_matrix(objects, invariance="combined")
    with threadpool_limits(1, user_api="blas"):
        d_one = pf.distance_matrix(objects, invariance="combined")
    assert np.array_equal(d_default, d_one)


def test_a_suspended_measurement_leaves_the_machines_threads(two_blas_threads):
    # iter_objects yields object by object: between two objects (a caller that computes, or
    # stops early) the caller's own products have the machine's BLAS threads
    yy, xx = np.mgrid[:64, :64]
    labels = np.zeros((2, 64, 64), np.uint16)
    for k in range(6):
        labels[:, ((yy - 10 - 9 * k) ** 2 + (xx - 32) ** 2) < 16] = k + 1
    objects = pf.iter_objects(labels)
    first = next(objects)
    assert first.label == 1 and _blas_threads() == 2
    objects.close()
    assert _blas_threads() == 2
