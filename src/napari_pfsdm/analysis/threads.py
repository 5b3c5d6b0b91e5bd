"""One BLAS thread while objects are measured: :func:`napari_pfsdm.core.threads.one_blas_thread`,
under the name the measuring modules import it by (the core's distances use it too, and the
core cannot import the analysis)."""

from __future__ import annotations

from ..core.threads import one_blas_thread

__all__ = ["one_blas_thread"]
