"""PFSDMParams: one validated record of the options, used by measure, the batch, the CLI."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

import napari_pfsdm as P
from napari_pfsdm.analysis.tracking import LINK_METHODS
from napari_pfsdm.cli import build_parser, main
from napari_pfsdm.core.morphometric import ring_radii, ring_weights
from napari_pfsdm.core.params import CHOICES, PFSDMParams


def labels():
    out = np.zeros((2, 64, 96), np.uint16)
    out[:, 10:50, 10:40] = 1
    out[1, 20:40, 55:90] = 2
    return out


def test_defaults_are_the_core_defaults_and_the_record_has_the_weights():
    p = PFSDMParams()
    assert {k: getattr(p, k) for k in P.DEFAULTS} == P.DEFAULTS
    rec = PFSDMParams(n_radii=8, ring_weighting="none").record()
    r = ring_radii(8, "uniform")
    assert rec["radii"] == r.tolist() and rec["n_radii"] == 8
    assert rec["weights"] == ring_weights(r, "none").tolist()
    assert PFSDMParams.from_options(rec) == PFSDMParams(n_radii=8, radii=tuple(r),
                                                         ring_weighting="none")


@pytest.mark.parametrize("options, message", [
    ({"mappng": "bijective"}, "unknown option mappng; the options are "),
    ({"mapping": "harmonc"}, "mapping must be one of harmonic, bijective, radial"),
    ({"n_fourier": 2.5}, "n_fourier must be a whole number >= 1"),
    ({"n_fourier": 40}, "n_fourier=40 needs more than 80 angles"),
    ({"viscosity": 0}, "viscosity must be a positive number"),
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


def test_the_command_line_offers_exactly_the_cores_choices(tmp_path, capsys):
    measure = next(a for a in build_parser()._subparsers._group_actions
                   if isinstance(a, argparse._SubParsersAction)).choices["measure"]
    offered = {a.dest: tuple(a.choices) for a in measure._actions if a.choices}
    # --link (following objects over time) is not a method option: it is the tracking's
    assert offered.pop("link") == ("auto", "none", *LINK_METHODS)
    assert offered == CHOICES
    assert main(["measure", str(tmp_path / "none.tif"), "-o", str(tmp_path / "f.csv"),
                 "--n-fourier", "40"]) == 2
    assert "n_fourier=40 needs more than 80 angles" in capsys.readouterr().err
