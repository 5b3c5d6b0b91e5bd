"""The per-object transforms (``core/fourier.py``) give scipy.fft's numbers to the bit, whether
they call pocketfft directly or through scipy.fft."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from scipy import fft as scipy_fft

from napari_pfsdm.core import fourier

RNG = np.random.default_rng(3)
#: The shapes the step transforms: an outline (256 points), the map's 48 rows of 64 angles, the
#: disk's 16 rings of 64 angles, and odd lengths.
SHAPES = [(256,), (48, 64), (16, 64), (7, 99), (1, 5)]


@pytest.mark.parametrize("which", ["direct", "through scipy.fft"])
@pytest.mark.parametrize("norm", ["backward", "forward"])
def test_transforms_equal_scipy_fft_to_the_bit(which, norm):
    transforms = (fourier._direct_transforms() if which == "direct"
                  else fourier._scipy_transforms())
    if transforms is None:
        pytest.skip("this scipy has no pocketfft extension to call directly")
    fft, ifft, rfft = transforms
    for shape in SHAPES:
        real = RNG.normal(size=shape)
        z = real + 1j * RNG.normal(size=shape)
        assert np.array_equal(fft(z, norm), scipy_fft.fft(z, norm=norm))
        assert np.array_equal(ifft(z, norm), scipy_fft.ifft(z, norm=norm))
        assert np.array_equal(rfft(real, norm), scipy_fft.rfft(real, norm=norm))
    # and the transforms do what they say: ifft(fft(z)) is z, rfft is fft's first half
    z = RNG.normal(size=64) + 1j * RNG.normal(size=64)
    np.testing.assert_allclose(ifft(fft(z, norm), norm), z, atol=1e-12)
    np.testing.assert_allclose(rfft(z.real, norm), fft(z.real + 0j, norm)[:33], atol=1e-12)


def test_the_module_calls_pocketfft_directly_on_this_scipy():
    assert fourier.DIRECT
    assert fourier.fft is not fourier._scipy_transforms()[0]


def test_a_scipy_without_the_extension_falls_back_to_scipy_fft(monkeypatch):
    monkeypatch.setitem(sys.modules, "scipy.fft._pocketfft.pypocketfft", None)
    monkeypatch.delattr("scipy.fft._pocketfft.pypocketfft", raising=False)
    assert fourier._direct_transforms() is None
