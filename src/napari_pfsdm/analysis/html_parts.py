"""The pieces of the HTML report: escaped text, inline PNG figures, tables (pure text; the page
itself is :mod:`napari_pfsdm.analysis.report`)."""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Sequence
from typing import Any

__all__ = ["DPI", "GENERATOR", "escaped", "figure", "image", "table_html"]

#: The ``<meta name="generator">`` a report carries: how napari-pfsdm recognises a report it
#: wrote (``io.written_by_pfsdm``), so that writing it again needs no ``--force``.
GENERATOR = "napari-pfsdm"
#: Resolution of the inline figures: small files, sharp enough on a screen.
DPI = 100


def escaped(value: Any) -> str:
    """``value`` as text safe inside HTML (quotes too)."""
    return html.escape(str(value), quote=True)


def image(fig, alt: str) -> str:
    """A matplotlib figure as an ``<img>`` of an inline PNG (``data:`` URI), described by
    ``alt``."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": GENERATOR})
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" alt="{escaped(alt)}">'


def figure(w: float, h: float):
    """A matplotlib figure of ``w`` × ``h`` inches, laid out to fit its texts."""
    from matplotlib.figure import Figure

    return Figure(figsize=(w, h), layout="constrained")


def table_html(rows: Sequence[Sequence[Any]], header: Sequence[str],
               numeric: Sequence[int] = ()) -> str:
    """An HTML table; the cells of the columns ``numeric`` right-aligned."""
    head = "".join(f"<th>{escaped(h)}</th>" for h in header)
    body = []
    for row in rows:
        cells = "".join(f'<td class="num">{escaped(v)}</td>' if i in numeric
                        else f"<td>{escaped(v)}</td>" for i, v in enumerate(row))
        body.append(f"<tr>{cells}</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"
