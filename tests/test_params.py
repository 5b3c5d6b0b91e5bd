"""The option record (core.params.OPTIONS, PFSDMParams): every door generated from it, every bad
value refused in the same words, a table's record checked before any work."""

from __future__ import annotations

import argparse
import inspect
import json
import re
import shutil
from dataclasses import fields
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone

import napari_pfsdm as P
from napari_pfsdm.analysis.transformer import PFSDMTransformer
from napari_pfsdm.cli import build_parser, main
from napari_pfsdm.cli.measure import _measure_options
from napari_pfsdm.core.descriptor3d import DEFAULTS_3D, pfsdm3d
from napari_pfsdm.core.morphometric import mode_weights, ring_radii, ring_weights
from napari_pfsdm.core.params import CHOICES, OPTIONS, PFSDMParams, check_record, option
from napari_pfsdm.errors import InputError
from napari_pfsdm.io import read_table, sidecar_path, write_table


def labels():
    out = np.zeros((2, 64, 96), np.uint16)
    out[:, 10:50, 10:40] = 1
    out[1, 20:40, 55:90] = 2
    return out


def test_the_record_has_the_weights():
    rec = PFSDMParams(n_radii=8, ring_weighting="none").record()
    r = np.array([0.0625, 0.1875, 0.3125, 0.4375, 0.5625, 0.6875, 0.8125, 0.9375])  # (i + ½)/8
    assert rec["radii"] == r.tolist() and rec["n_radii"] == 8
    assert rec["weights"] == [0.125] * 8  # each ring's cell is 1/8 wide, no weighting
    assert PFSDMParams.from_options(rec) == PFSDMParams(n_radii=8, radii=tuple(r),
                                                         ring_weighting="none")


def test_ring_placements_and_weightings_are_their_closed_forms():
    # "uniform": (i + ½)/4; "boundary": 1 − ((i + ½)/4)², sorted
    np.testing.assert_array_equal(ring_radii(4, "uniform"), [0.125, 0.375, 0.625, 0.875])
    rb = ring_radii(4, "boundary")
    np.testing.assert_allclose(rb, [0.234375, 0.609375, 0.859375, 0.984375], rtol=1e-15)
    # cells between midpoints, 0 and 1 at the ends: widths computed by hand
    cells = [0.421875, 0.3125, 0.1875, 0.078125]
    np.testing.assert_allclose(ring_weights(rb, "none"), cells, rtol=1e-14)
    np.testing.assert_allclose(ring_weights(rb, "depth"),
                               np.array(cells) / (1 - rb) ** 2, rtol=1e-14)
    np.testing.assert_allclose(ring_weights(rb, "boundary"),
                               np.array(cells) / (1 - rb + 0.05), rtol=1e-14)
    # one ring at ½: the whole interval; depth 1/(½)² = 4, boundary 1/0.55
    assert ring_weights(np.array([0.5]), "none").tolist() == [1.0]
    assert ring_weights(np.array([0.5]), "depth").tolist() == [4.0]
    assert ring_weights(np.array([0.5]), "boundary")[0] == pytest.approx(1 / 0.55, rel=1e-15)
    np.testing.assert_allclose(mode_weights(3, 0.5), [1.0, 2**0.5, 3**0.5, 2.0], rtol=1e-15)
    assert mode_weights(2, 0.0).tolist() == [1.0, 1.0, 1.0]
    # the quadrature integrates: Σ w_i r_i ≈ ∫₀¹ r dr = ½ exactly for the midpoint rule
    assert float(ring_weights(ring_radii(16), "none") @ ring_radii(16)) == pytest.approx(0.5)
    with pytest.raises(ValueError, match="ring_weighting must be one of"):
        ring_weights(rb, "deep")
    with pytest.raises(ValueError, match="strictly between 0 and 1"):
        ring_radii(3, [0.0, 0.5])
    with pytest.raises(ValueError, match="mode_exponent must be a number >= 0"):
        mode_weights(3, -0.1)


@pytest.mark.parametrize("options, message", [
    ({"mappng": "bijective"}, "unknown option mappng; the options are "),
    ({"mapping": "harmonc"}, "mapping must be one of harmonic, bijective, radial"),
    ({"n_fourier": 2.5}, "n_fourier must be a whole number from 1 to 256; got 2.5."),
    ({"n_fourier": 40}, "n_fourier=40 needs more than 80 angles"),
    ({"viscosity": 0}, "viscosity must be a number above 0 and at most 1; got 0."),
])
def test_bad_options_fail_before_any_work(options, message):
    with pytest.raises(ValueError, match=message):
        PFSDMParams.from_options(options)
    with pytest.raises(ValueError, match=message):
        P.measure(labels(), progress=lambda *a: pytest.fail("work started"), **options)


def test_params_or_keywords_give_the_same_table():
    a = P.measure(labels(), params=PFSDMParams(n_fourier=6, n_radii=8))
    b = P.measure(labels(), n_fourier=6, n_radii=8)
    assert a.equals(b) and a.attrs == b.attrs
    with pytest.raises(ValueError, match="not both"):
        P.measure(labels(), params=PFSDMParams(), n_fourier=6)




# ------------------------------------------------------------------ one record, every door

def _measure_parser() -> argparse.ArgumentParser:
    return next(a for a in build_parser()._subparsers._group_actions
                if isinstance(a, argparse._SubParsersAction)).choices["measure"]


def _words(text: str) -> str:
    return " ".join(text.split())


def test_every_door_shows_the_records_default_help_and_choices(capsys):
    """pfsdm(), measure(), DEFAULTS, the transformer, PFSDMParams and the command line are
    generated from OPTIONS: for every option each shows OPTIONS' default, help and choices."""
    actions = {a.dest: a for a in _measure_parser()._actions}
    transformer = PFSDMTransformer().get_params()
    signature = inspect.signature(P.pfsdm).parameters
    for_measure = inspect.signature(P.measure).parameters
    for_volumes = inspect.signature(pfsdm3d).parameters  # 3-D objects: the same record
    record_fields = {f.name: f for f in fields(PFSDMParams)}
    with pytest.raises(SystemExit):
        main(["measure", "--help"])
    shown = _words(capsys.readouterr().out)
    for o in OPTIONS:
        assert (P.DEFAULTS[o.name] == transformer[o.name] == signature[o.name].default
                == for_measure[o.name].default == for_volumes[o.name].default
                == getattr(PFSDMParams(), o.name) == o.default), o.name
        assert record_fields[o.name].metadata["option"] is o
        action = actions[o.name]
        assert action.option_strings == [o.flag] == ["--" + o.name.replace("_", "-")]
        assert action.default is None  # left out: the core's default
        assert (tuple(action.choices) if action.choices else None) == o.choices
        assert _words(f"{o.help} (default {o.default})") in shown, o.name
    assert list(P.DEFAULTS) == [f.name for f in fields(PFSDMParams)] == [o.name for o in OPTIONS]
    assert CHOICES == {o.name: o.choices for o in OPTIONS if o.choices}
    assert DEFAULTS_3D == {o.name: o.default for o in OPTIONS if o.dims == "3d"}
    assert sorted(o.name for o in OPTIONS if o.basic) == [
        "border_objects", "mapping", "min_area", "n_fourier", "n_radii", "profile_bins", "sdf",
        "warned_objects"]


#: A value other than the default for every option (consistent with one another).
CHANGED = {"n_fourier": 7, "n_radii": 5, "n_angles": 40, "sdf": "viscous", "viscosity": 0.2,
           "mapping": "radial", "normalization": "ring", "radii": "boundary",
           "ring_weighting": "none", "mode_exponent": 0.5, "elastic_smoothing": 2.0,
           "elastic_signature": "table",
           "components": "raise", "min_area": 11, "border_objects": "leave_out",
           "warned_objects": "leave_out", "sh_degree": 4, "surface_weight": 2.0,
           "ball_map": "harmonic", "profile_bins": 6, "anterior": "first"}


def test_an_option_given_at_any_door_reaches_the_record():
    assert set(CHANGED) == {o.name for o in OPTIONS}
    assert all(CHANGED[o.name] != o.default for o in OPTIONS)
    want = PFSDMParams(**CHANGED)
    argv = ["measure", "x.tif", "-o", "f.csv"]
    for name, value in CHANGED.items():
        argv += [option(name).flag, str(value)]
    assert _measure_options(build_parser().parse_args(argv)) == CHANGED
    assert _measure_options(build_parser().parse_args(argv[:4])) == {}
    assert PFSDMTransformer(**CHANGED)._params() == want
    assert clone(PFSDMTransformer(**CHANGED)).get_params() == {**CHANGED, "spacing": None,
                                                               "weighted": False}
    two_d = {o.name: CHANGED[o.name] for o in OPTIONS if o.dims != "3d"}
    res = P.pfsdm(labels()[1] == 1, **two_d)
    assert res.embedding.shape == (5, 8)
    assert {k: res.options[k] for k in ("n_fourier", "n_angles", "sdf", "viscosity", "mapping",
                                        "normalization", "ring_weighting", "mode_exponent")} \
        == {k: CHANGED[k] for k in ("n_fourier", "n_angles", "sdf", "viscosity", "mapping",
                                    "normalization", "ring_weighting", "mode_exponent")}
    assert res.radii.tolist() == ring_radii(5, "boundary").tolist()


def test_the_sidecar_door_carries_every_option_as_the_record_says(tmp_path):
    """A table's sidecar holds every option of the record, defaults and changed values alike,
    and gives back the same PFSDMParams: what a table was measured with is never lost."""
    for params in (PFSDMParams(), PFSDMParams(**CHANGED)):
        path = write_table(pd.DataFrame({"area": [1.0]}), tmp_path / "t.csv",
                               params.record())
        written = json.loads(sidecar_path(path).read_text())["options"]
        assert {o.name for o in OPTIONS} <= set(written)
        back = read_table(path).attrs["pfsdm"]
        # the rings are recorded as their radii (a placement's name becomes its numbers)
        assert back["radii"] == ring_radii(params.n_radii, params.radii).tolist()
        assert all(back[o.name] == getattr(params, o.name) for o in OPTIONS
                   if o.name != "radii"), back
        again = PFSDMParams.from_options({o.name: back[o.name] for o in OPTIONS})
        assert again.record() == params.record()


#: Bad values: out of range (10**12 Fourier modes would allocate gigabytes), the wrong type,
#: not finite, not whole.
BAD = [("n_fourier", 0), ("n_fourier", 10**12), ("n_fourier", "ten"), ("n_radii", 10**6),
       ("n_angles", 9999), ("viscosity", float("nan")), ("viscosity", float("inf")),
       ("mode_exponent", -1.0), ("mapping", "harmonc"), ("min_area", 2.5), ("sh_degree", 41),
       ("surface_weight", -4.0)]


@pytest.mark.parametrize("name, value", BAD)
def test_a_bad_value_gets_the_same_words_at_every_door(name, value, tmp_path, capsys):
    words = option(name).message(value)
    assert words.startswith(f"{name} must be ")
    mask = labels()[0] == 1

    def no_work(*args):
        pytest.fail("work started")

    doors = {
        "PFSDMParams": lambda: PFSDMParams(**{name: value}),
        "pfsdm": lambda: P.pfsdm(mask, **{name: value}),
        "measure": lambda: P.measure(labels(), progress=no_work, **{name: value}),
        "transformer": lambda: PFSDMTransformer(**{name: value}).fit([mask]),
        "a table's record": lambda: check_record({name: value}),
    }
    # a table's sidecar naming the value: refused when the table is read, before any row
    table = tmp_path / "t.csv"
    write_table(pd.DataFrame({"area": [1.0]}), table, {name: value})
    doors["a table's sidecar"] = lambda: read_table(table)
    for door, call in doors.items():
        with pytest.raises(InputError) as info:
            call()
        assert words in str(info.value), door
    # the command line: argparse's line names the flag, then the same words, exit status 2
    with pytest.raises(SystemExit) as stop:
        main(["measure", str(tmp_path / "none.tif"), "-o", str(tmp_path / "f.csv"),
              option(name).flag, str(value)])
    assert stop.value.code == 2
    assert f"argument {option(name).flag}: {words}" in capsys.readouterr().err


def test_a_rule_between_options_is_checked_by_the_command_line_before_any_file(tmp_path,
                                                                            capsys):
    assert main(["measure", str(tmp_path / "none.tif"), "-o", str(tmp_path / "f.csv"),
                 "--n-fourier", "40"]) == 2
    assert capsys.readouterr().err == ("pfsdm: error: n_fourier=40 needs more than 80 angles; "
                                       "raise n_angles.\n")


def test_wrong_types_are_refused_in_plain_words_not_as_internal_errors():
    for name, value in [("n_radii", True), ("n_radii", None), ("viscosity", "0.1"),
                        ("sdf", 1), ("radii", ["a"]), ("radii", [0.5] * 513),
                        ("mode_exponent", [0.5])]:
        with pytest.raises(InputError, match=f"^{name} must be "):
            PFSDMParams(**{name: value})
    # numbers that are whole are whole numbers, numpy's too
    assert PFSDMParams(n_fourier=6.0, n_radii=np.int64(8), viscosity=np.float32(0.5)) \
        == PFSDMParams(n_fourier=6, n_radii=8, viscosity=0.5)


# ------------------------------------------------------------------ a table's record on disk

@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("sidecar") / "features.csv"
    write_table(P.measure(labels()), path)
    return path


def _nan_weight(o):
    o["weights"][3] = float("nan")


def _inf_weight(o):
    o["weights"][0] = float("inf")


def _negative_weight(o):
    o["weights"][5] = -o["weights"][5]


def _four_weights(o):
    o["weights"] = o["weights"][:4]


def _nan_mode_weight(o):
    o["mode_weights"][2] = float("nan")


def _three_mode_weights(o):
    o["mode_weights"] = o["mode_weights"][:3]


def _huge_n_fourier(o):
    o["n_fourier"] = 10**12


def _text_n_fourier(o):
    o["n_fourier"] = "ten"


def _text_weights(o):
    o["weights"] = "1, 2, 3"


@pytest.mark.parametrize("damage, words", [
    (_nan_weight, "weights must be 16 numbers of at least 0 and at most 1e+12, one per ring "
                  "(not all 0); got "),
    (_inf_weight, "weights must be 16 numbers of at least 0"),
    (_negative_weight, "weights must be 16 numbers of at least 0"),
    (_four_weights, "weights has 4 numbers but the table has 16 rings"),
    (_nan_mode_weight, "mode_weights must be 11 numbers of at least 0 and at most 1e+12, one "
                       "per Fourier index"),
    (_three_mode_weights, "mode_weights has 3 numbers but the table has 11 Fourier indices"),
    (_huge_n_fourier, option("n_fourier").message(10**12)),
    (_text_n_fourier, option("n_fourier").message("ten")),
    (_text_weights, "weights must be 16 numbers of at least 0"),
])
def test_a_damaged_record_is_refused_before_any_work(written, tmp_path, capsys, damage, words):
    """NaN, inf or negative weights once gave an all-NaN distance matrix with exit status 0,
    4 weights instead of 16 silently other distances, n_fourier 10**12 gigabytes."""
    path = tmp_path / "features.csv"
    shutil.copy(written, path)
    side = json.loads(sidecar_path(written).read_text())
    damage(side["options"])
    sidecar_path(path).write_text(json.dumps(side))
    with pytest.raises(InputError) as info:
        read_table(path)
    assert words in str(info.value) and str(path) in str(info.value)
    assert main(["compare", str(path), "-o", str(tmp_path / "d.csv"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pfsdm: error: the options of ") and words in err
    assert not (tmp_path / "d.csv").exists()
    # the same record carried in memory is refused by the distances too
    table = read_table(written)
    damage(table.attrs["pfsdm"])
    with pytest.raises(InputError, match=re.escape(words)):
        P.distance_matrix(table)


def test_a_record_that_belongs_to_another_table_is_refused(written, tmp_path):
    """Without n_radii and radii to count against, 4 weights on a 16-ring table would use the
    first 4 rings only: the extra feature columns give it away."""
    table = read_table(written)
    for key in ("n_radii", "radii"):
        del table.attrs["pfsdm"][key]
    table.attrs["pfsdm"]["weights"] = table.attrs["pfsdm"]["weights"][:4]
    with pytest.raises(InputError, match="has 132 shape feature columns more than its options "
                                         "account for"):
        P.distance_matrix(table)
    side = json.loads(sidecar_path(written).read_text())
    side["options"] = ["not", "a", "record"]
    path = tmp_path / "features.csv"
    shutil.copy(written, path)
    sidecar_path(path).write_text(json.dumps(side))
    with pytest.raises(InputError, match="are not a set of named options"):
        read_table(path)


def test_a_table_in_memory_with_a_damaged_dimension_is_refused_in_plain_words(written):
    table = read_table(written)
    table.attrs["pfsdm"]["ndim"] = "abc"
    with pytest.raises(InputError, match="ndim 'abc': it must be 2 or 3"):
        P.distance_matrix(table)


def test_a_good_record_reads_as_written(written):
    table = read_table(written)
    check_record(table.attrs["pfsdm"])
    assert PFSDMParams.from_options(table.attrs["pfsdm"]).options()["n_fourier"] == 10
    assert np.isfinite(P.distance_matrix(table)).all()
