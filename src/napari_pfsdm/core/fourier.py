"""The discrete Fourier transforms of one object's step, without scipy.fft's dispatch.

``scipy.fft`` and ``numpy.fft`` run the same pocketfft (the same bits). Around it, each call
to ``scipy.fft`` passes its backend dispatch and argument checks, about 5 µs a call: as much
as transforming one object's 64–256 numbers, and an object's step makes five calls. This
module calls scipy's pocketfft extension directly, along the last axis, when the installed
scipy has it with the signature it is called with here and it gives ``scipy.fft``'s numbers to
the bit on a test array (checked once, at import); otherwise it calls ``scipy.fft``. The
numbers are the same either way (``tests/test_fourier.py``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import fft as _scipy_fft

__all__ = ["DIRECT", "fft", "ifft", "rfft"]

#: pocketfft's scaling codes: none, 1/√n, 1/n (``scipy.fft``'s ``norm`` of a forward
#: transform: "backward", "ortho", "forward"; an inverse one uses the opposite).
_SCALE = {"backward": 0, "forward": 2}


def _scipy_transforms() -> tuple[Callable, Callable, Callable]:
    def fft(x: np.ndarray, norm: str = "backward") -> np.ndarray:
        return _scipy_fft.fft(x, norm=norm)

    def ifft(x: np.ndarray, norm: str = "backward") -> np.ndarray:
        return _scipy_fft.ifft(x, norm=norm)

    def rfft(x: np.ndarray, norm: str = "backward") -> np.ndarray:
        return _scipy_fft.rfft(x, norm=norm)

    return fft, ifft, rfft


def _direct_transforms() -> tuple[Callable, Callable, Callable] | None:
    """pocketfft's ``c2c`` and ``r2c`` on the last axis, or None when this scipy has them
    under another name or signature, or they differ from ``scipy.fft`` by a bit."""
    try:
        from scipy.fft._pocketfft import pypocketfft as pocketfft

        c2c, r2c = pocketfft.c2c, pocketfft.r2c
    except (ImportError, AttributeError):
        return None

    def fft(x: np.ndarray, norm: str = "backward") -> np.ndarray:
        return c2c(x, (x.ndim - 1,), True, _SCALE[norm], None, 1)

    def ifft(x: np.ndarray, norm: str = "backward") -> np.ndarray:
        return c2c(x, (x.ndim - 1,), False, 2 - _SCALE[norm], None, 1)

    def rfft(x: np.ndarray, norm: str = "backward") -> np.ndarray:
        return r2c(x, (x.ndim - 1,), True, _SCALE[norm], None, 1)

    direct = fft, ifft, rfft
    rng = np.random.default_rng(0)
    real = rng.normal(size=(3, 64))
    cplx = real + 1j * rng.normal(size=real.shape)
    try:
        for ours, theirs, x in zip(direct, _scipy_transforms(), (cplx, cplx, real),
                                   strict=True):
            for norm in _SCALE:
                if not np.array_equal(ours(x, norm), theirs(x, norm)):
                    return None
    except Exception:  # noqa: BLE001 - any change of the private API: use scipy.fft
        return None
    return direct


_DIRECT = _direct_transforms()
#: Whether the transforms call pocketfft directly (False: through ``scipy.fft``).
DIRECT = _DIRECT is not None
fft, ifft, rfft = _DIRECT or _scipy_transforms()
fft.__doc__ = ("``scipy.fft.fft(x, norm=norm)`` along the last axis of a complex array "
               "(``norm``: \"backward\" or \"forward\").")
ifft.__doc__ = ("``scipy.fft.ifft(x, norm=norm)`` along the last axis of a complex array "
                "(``norm``: \"backward\" or \"forward\").")
rfft.__doc__ = ("``scipy.fft.rfft(x, norm=norm)`` along the last axis of a real array "
                "(``norm``: \"backward\" or \"forward\").")
