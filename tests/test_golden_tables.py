"""Every path that measures (``pf.measure``, the process pool of the plugin's Run, dask's
schedulers, the batch behind ``pfsdm measure``, the plugin's ``run_analysis``) makes the same
table of the same inputs, byte for byte, as the reference tables in ``tests/data/golden/``
(``tests/golden_tables.py`` writes them)."""

from __future__ import annotations

import pandas as pd
import pytest
import tifffile

import napari_pfsdm as pf
from golden_tables import csv_text, inputs, reference
from napari_pfsdm.analysis import parallel
from napari_pfsdm.analysis.row_blocks import join_blocks
from napari_pfsdm.batch.tasks import measure_dask
from napari_pfsdm.core.params import PFSDMParams

INPUTS = inputs()
NAMES = list(INPUTS)


def _split(kw: dict) -> tuple[dict, PFSDMParams]:
    where = {k: kw[k] for k in ("axes", "spacing") if k in kw}
    return where, PFSDMParams(**{k: v for k, v in kw.items() if k not in where})


def _same(table: pd.DataFrame, name: str) -> None:
    text, ref = csv_text(table), reference(name)
    if text != ref:  # say where, not just that
        got = pd.read_csv(pd.io.common.StringIO(text))
        want = pd.read_csv(pd.io.common.StringIO(ref))
        assert list(got.columns) == list(want.columns)
        assert got.shape == want.shape
        diff = [c for c in want.columns if not got[c].equals(want[c])]
        raise AssertionError(f"{name}: columns differ from the reference: {diff[:10]}")


@pytest.mark.parametrize("name", NAMES)
def test_measure_makes_the_reference_table(name):
    labels, intensity, kw = INPUTS[name]
    _same(pf.measure(labels, intensity, **kw), name)


@pytest.mark.parametrize("name", NAMES)
def test_the_process_pool_makes_the_reference_table(name, monkeypatch):
    labels, intensity, kw = INPUTS[name]
    where, params = _split(kw)
    monkeypatch.setattr(parallel, "MIN_OBJECTS", 1)  # small inputs, still in processes
    monkeypatch.setattr(parallel, "MIN_TASK_OBJECTS", 1)
    axes = where.get("axes", "tyx")
    gen = parallel.iter_blocks(labels, intensity, params=params, axes=axes,
                               spacing=where.get("spacing"), workers=2)
    try:
        while True:
            next(gen)
    except StopIteration as stop:
        blocks = stop.value
    assert len(blocks) > 1  # really split between tasks
    _same(join_blocks(blocks).table, name)


@pytest.mark.parametrize("scheduler", ["threads", "processes"])
@pytest.mark.parametrize("name", NAMES)
def test_dask_makes_the_reference_table(name, scheduler):
    labels, intensity, kw = INPUTS[name]
    where, params = _split(kw)
    _same(measure_dask(labels, intensity, scheduler=scheduler, num_workers=2, params=params,
                       **where), name)


@pytest.mark.parametrize("name", NAMES)
def test_the_batch_makes_the_reference_table(name, tmp_path):
    from napari_pfsdm.batch.movies import Movie
    from napari_pfsdm.batch.run import run_batch

    labels, intensity, kw = INPUTS[name]
    where, params = _split(kw)
    tifffile.imwrite(tmp_path / "m.tif", labels)
    if intensity is not None:  # in its own dtype: the same numbers read back
        tifffile.imwrite(tmp_path / "m_reporter.tif", intensity)
    movie = Movie("m", tmp_path / "m.tif",
                  tmp_path / "m_reporter.tif" if intensity is not None else None)
    run_batch([movie], tmp_path / "out.csv", params=params, **where)
    got = pf.read_table(tmp_path / "out.csv")
    assert (got["movie"] == "m").all()
    _same(got.drop(columns="movie"), name)


@pytest.mark.parametrize("name", NAMES)
def test_the_plugins_run_makes_the_reference_table(name):
    from napari_pfsdm.napari._results import run_analysis

    labels, intensity, kw = INPUTS[name]
    where, params = _split(kw)
    first = "time"
    gen = run_analysis(labels, intensity, params=params, first_axis=first,
                       spacing=where.get("spacing"), workers=2)
    try:
        while True:
            next(gen)
    except StopIteration as stop:
        fields = stop.value
    _same(fields["table"], name)
