"""The elastic term's compiled kernels are compiled once: a second process loads them from numba's
cache, and the first compile is said (core.compiled)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

#: A fresh process that uses the kernels (``which``: "signature" or "all") inside
#: compile_notice, then prints what it heard and numba's own count of each kernel's cache
#: hits and misses (compiles).
SCRIPT = textwrap.dedent("""
    import json, sys
    import numpy as np
    from napari_pfsdm.core.compiled import compile_notice
    from napari_pfsdm.core.elastic_signature import outline_signature

    heard = []
    which = sys.argv[1]
    t = 2 * np.pi * np.arange(256) / 256
    with compile_notice(heard.append):
        sig = np.stack([outline_signature(np.column_stack(
            [np.cos(t) * (1 + 0.2 * np.cos(k * t)), np.sin(t)])) for k in range(2, 8)])
        if which == "all":
            from napari_pfsdm.core.elastic import (SignatureSet, elastic_distance_matrix,
                                                   elastic_nearest)

            d = elastic_distance_matrix(sig)
            cand = np.argsort(d + 9 * np.eye(6), axis=1)[:, :4]
            elastic_nearest(sig, cand, np.zeros(cand.shape), 0.5, 2)
            SignatureSet(sig).between(np.arange(6), np.arange(6)[::-1], here=True)
    from napari_pfsdm.core import signature_kernel
    kernels = {"signature": signature_kernel.signature}
    if which == "all":
        from napari_pfsdm.core import elastic_kernel
        kernels.update(pairs=elastic_kernel.pairs, nearest=elastic_kernel.nearest,
                       pairs_here=elastic_kernel.pairs_here)
    stats = {name: [sum(k.stats.cache_hits.values()), sum(k.stats.cache_misses.values())]
             for name, k in kernels.items()}
    print(json.dumps({"heard": heard, "stats": stats}))
""")


def _fresh_process(which: str, cache: str | None) -> dict:
    env = dict(os.environ)
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = cache
    out = subprocess.run([sys.executable, "-c", SCRIPT, which], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_the_first_compile_is_said_and_a_second_process_loads_it(tmp_path):
    # an empty cache folder: the first process compiles the signature's kernel and says so;
    # the second loads it from the folder and says nothing
    cache = str(tmp_path / "numba_cache")
    first = _fresh_process("signature", cache)
    assert first["stats"]["signature"][1] == 1  # compiled
    assert len(first["heard"]) == 1
    assert first["heard"][0].startswith("compiling the elastic kernel, once (the outline "
                                        "signature")
    second = _fresh_process("signature", cache)
    assert second["stats"]["signature"] == [1, 0]  # loaded, not compiled
    assert second["heard"] == []


@pytest.mark.slow
def test_a_second_process_loads_every_elastic_kernel_from_the_cache():
    # numba's own cache (beside the package, as a user has it): whatever the first process
    # had to compile, the second compiles nothing (closures that capture compiled functions
    # missed it in every process: numba issue #6264)
    _fresh_process("all", None)
    second = _fresh_process("all", None)
    for name, (hits, misses) in second["stats"].items():
        assert (hits, misses) == (1, 0), name
    assert second["heard"] == []
