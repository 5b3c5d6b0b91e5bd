"""Names as a plot shows them: as written, never read as math text or hidden.

matplotlib reads text between two ``$`` as math (``cost $5 vs $_`` is drawn in italics, or
stops the drawing with a parse error), and leaves out of a legend every label that starts with
``_``. Group, movie, column, layer and file names are the user's words: every place a name
reaches a figure's text (a title, a legend, an axis or tick label, an annotation) passes it
through :func:`plot_text` once (tests/test_faults_names.py draws every figure with such names
and checks what is drawn).
"""

from __future__ import annotations

from typing import Any

__all__ = ["plot_text"]

#: Put before a name that starts with "_", which matplotlib would leave out of a legend: the
#: zero-width space, drawn as nothing.
_VISIBLE = "\u200b"


def plot_text(value: Any) -> str:
    """``value`` as text that matplotlib draws as it is: every ``$`` escaped (no math text)
    and a leading ``_`` kept in legends.

    Examples
    --------
    >>> plot_text("cost $5 vs $_")
    'cost \\\\$5 vs \\\\$_'
    >>> plot_text("_hidden").lstrip("\\u200b")
    '_hidden'
    """
    text = str(value).replace("$", r"\$")
    return _VISIBLE + text if text.startswith("_") else text
