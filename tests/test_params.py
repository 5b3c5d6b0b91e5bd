"""PFSDMParams: one validated record of the options, used by measure, the batch, the CLI."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

import napari_pfsdm as P
from napari_pfsdm.analysis.tracking import LINK_METHODS
from napari_pfsdm.cli import build_parser, main
from napari_pfsdm.core.morphometric import mode_weights, ring_radii, ring_weights
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


def _method_option_names_and_defaults() -> dict:
    from dataclasses import fields

    return {f.name: f.default for f in fields(PFSDMParams)}


#: Keywords of pfsdm() that are not method options: the input and implementation details of
#: the outline and the display (fixed by the benchmarks, not offered by the CLI or the widget).
PFSDM_NOT_OPTIONS = {"mask", "intensity", "smooth", "degree", "grid", "offset", "spacing"}


def test_pfsdm_signature_declares_exactly_the_params_options():
    """The method's options are declared once (PFSDMParams): pfsdm()'s keywords must be the
    same names with the same defaults; this fails when one of them drifts."""
    import inspect

    from napari_pfsdm.core.descriptor import pfsdm

    sig = inspect.signature(pfsdm).parameters
    got = {k: v.default for k, v in sig.items() if k not in PFSDM_NOT_OPTIONS}
    assert got == _method_option_names_and_defaults()


def test_the_transformer_takes_exactly_the_params_options():
    import inspect

    from napari_pfsdm.analysis.transformer import PFSDMTransformer

    sig = inspect.signature(PFSDMTransformer.__init__).parameters
    got = {k: v.default for k, v in sig.items() if k not in ("self", "spacing", "weighted")}
    assert got == _method_option_names_and_defaults()
    # and each reaches the core's record (a parameter stored but not passed on would not)
    options = {"n_fourier": 7, "n_radii": 5, "n_angles": 40, "sdf": "viscous",
               "viscosity": 0.2, "mapping": "radial", "normalization": "ring",
               "radii": "boundary", "ring_weighting": "none", "mode_exponent": 0.5,
               "components": "raise", "min_area": 11, "sh_degree": 4, "surface_weight": 2.0,
               "ball_map": "harmonic"}
    assert set(options) == set(_method_option_names_and_defaults())
    assert PFSDMTransformer(**options)._params() == PFSDMParams(**options)


def test_the_command_line_offers_exactly_the_params_options():
    """``pfsdm measure`` has one option per PFSDMParams field (``--n-fourier`` for
    ``n_fourier``), each passed on to the core: parsed values reach the record."""
    from napari_pfsdm.cli import _measure_options

    measure = next(a for a in build_parser()._subparsers._group_actions
                   if isinstance(a, argparse._SubParsersAction)).choices["measure"]
    group = next(g for g in measure._action_groups if g.title.startswith("method options"))
    dests = {a.dest: a.option_strings for a in group._group_actions}
    names = set(_method_option_names_and_defaults())
    assert set(dests) == names
    assert all(dests[n] == ["--" + n.replace("_", "-")] for n in names)
    argv = ["measure", "x.tif", "-o", "f.csv", "--n-fourier", "7", "--n-radii", "5",
            "--n-angles", "40", "--sdf", "viscous", "--viscosity", "0.2", "--mapping", "radial",
            "--normalization", "ring", "--radii", "boundary", "--ring-weighting", "none",
            "--mode-exponent", "0.5", "--components", "raise", "--min-area", "11",
            "--sh-degree", "4", "--surface-weight", "2", "--ball-map", "harmonic"]
    got = _measure_options(build_parser().parse_args(argv))
    assert got == {"n_fourier": 7, "n_radii": 5, "n_angles": 40, "sdf": "viscous",
                   "viscosity": 0.2, "mapping": "radial", "normalization": "ring",
                   "radii": "boundary", "ring_weighting": "none", "mode_exponent": 0.5,
                   "components": "raise", "min_area": 11, "sh_degree": 4,
                   "surface_weight": 2.0, "ball_map": "harmonic"}
    assert _measure_options(build_parser().parse_args(argv[:4])) == {}  # defaults: the core's


def test_pfsdm3d_takes_its_method_options_from_params():
    import inspect

    from napari_pfsdm.core.descriptor3d import DEFAULTS_3D, pfsdm3d

    sig = inspect.signature(pfsdm3d).parameters
    every = _method_option_names_and_defaults()
    shared = {"n_radii", "radii", "ring_weighting", "mode_exponent", "sh_degree", "ball_map",
              "surface_weight", "components"}
    assert {k: sig[k].default for k in shared} == {k: every[k] for k in shared}
    assert DEFAULTS_3D == {k: every[k] for k in ("sh_degree", "ball_map", "surface_weight")}
