"""The elastic outline term in the plots dock: the check box of the Distances and Similar tabs,
and numba's first compile of its kernels said in the tab.

The term (docs/method.md, "The elastic outline term") adds
:data:`~napari_pfsdm.core.distances.RECOMMENDED_ELASTIC_WEIGHT` × d_E to the PF-SDM distance:
better retrieval among articulated or detailed outlines, nothing gained on round nuclei. It
compares the objects' outline signatures, which a run measures with ``elastic_signature`` =
table (More options); without them the tab says so.
"""

from __future__ import annotations

from magicgui.widgets import CheckBox, Label
from superqt.utils import ensure_main_thread

from ..core.distances import RECOMMENDED_ELASTIC_WEIGHT

TIP = (f"Add the elastic outline term (weight {RECOMMENDED_ELASTIC_WEIGHT:g}): better "
       "retrieval among articulated or detailed outlines (limbs, notches); nothing gained on "
       "round nuclei. Needs a run with elastic_signature = table (More options).")


def elastic_box() -> CheckBox:
    """The tab's "elastic" check box (off)."""
    return CheckBox(text="elastic", value=False, tooltip=TIP)


def weight_of(box: CheckBox) -> float:
    """μ of the distance the tab shows: the recommended weight when ticked, else 0."""
    return RECOMMENDED_ELASTIC_WEIGHT if box.value else 0.0


def notice(info: Label):
    """A sink for :func:`napari_pfsdm.core.compiled.compile_notice`: the message in the tab's
    info line, from whichever thread compiles (the worker's)."""
    @ensure_main_thread
    def say(message: str) -> None:
        info.value = message[:1].upper() + message[1:] + "…"

    return say
