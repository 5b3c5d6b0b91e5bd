"""Text a spreadsheet would run as a formula, written so that it is shown as text.

Text cells starting with ``= + - @``, a tab or a carriage return (a movie or group named
``=cmd|...``: OWASP's "CSV injection") are written with a single quote in front, so that Excel
or LibreOffice show them as text; numbers, negative ones included, are left alone. The
sidecar says so (:data:`ESCAPE_KEY`) and the reader removes exactly that quote again: names
read back as they were.
"""

from __future__ import annotations

import re
from typing import Any

import pandas as pd

__all__ = ["ESCAPE_KEY", "FORMULA_STARTS", "escape_formulas", "has_carriage_return",
           "unescape_formulas"]

#: A text cell that a spreadsheet would run as a formula starts with one of these (OWASP's
#: "CSV injection"); such a cell is written with a single quote in front, which a spreadsheet
#: shows as text and :func:`read_table` removes again.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
#: A cell written with the quote: the quote(s), then a formula's first character. A name that
#: already starts with quotes before such a character gets one more, so that reading back
#: removes exactly the one that writing added.
_ESCAPED = re.compile(r"'+[=+\-@\t\r]")
_TO_ESCAPE = re.compile(r"'*[=+\-@\t\r]")
#: The sidecar's entry saying that text cells were written escaped (its value: the prefix).
ESCAPE_KEY = "text_escape"


def _escape_cell(value: Any) -> Any:
    if isinstance(value, str) and _TO_ESCAPE.match(value):
        return "'" + value
    return value


def _unescape_cell(value: Any) -> Any:
    if isinstance(value, str) and _ESCAPED.match(value):
        return value[1:]
    return value


def _text_like(values: pd.Index | pd.Series) -> bool:
    return values.dtype == object or pd.api.types.is_string_dtype(values.dtype)


def has_carriage_return(df: pd.DataFrame) -> bool:
    """Whether a text cell, column name or index label of ``df`` holds a carriage return."""
    names = [*df.columns, *(df.index if _text_like(df.index) else [])]
    if any(isinstance(v, str) and "\r" in v for v in names):
        return True
    return any(df[c].map(lambda v: isinstance(v, str) and "\r" in v).any()
               for c in df.columns if _text_like(df[c]))


def escape_formulas(df: pd.DataFrame) -> pd.DataFrame:
    """A copy of ``df`` whose text cells (and text column names and index labels) that a
    spreadsheet would run as a formula (starting with ``= + - @``, a tab or a carriage
    return) start with a single quote instead; numbers, negative ones included, are left as
    they are. :func:`unescape_formulas` undoes it exactly.

    Examples
    --------
    >>> import pandas as pd
    >>> escape_formulas(pd.DataFrame({"movie": ["=1+1", "e1"], "x": [-1.5, 2.0]})).values.tolist()
    [["'=1+1", -1.5], ['e1', 2.0]]
    """
    # the numbers are not copied: only text columns change
    return _map_text(df.copy(deep=False), _escape_cell)


def unescape_formulas(df: pd.DataFrame) -> pd.DataFrame:
    """Undo :func:`escape_formulas` (in place; returns ``df``): one leading quote removed from
    text cells, column names and index labels that start with quotes and then ``= + - @``,
    a tab or a carriage return."""
    return _map_text(df, _unescape_cell)


def _map_text(df: pd.DataFrame, cell) -> pd.DataFrame:
    """``cell`` applied to ``df``'s text columns, column names and text index (in place)."""
    for col in df.columns:
        if _text_like(df[col]):
            df[col] = df[col].map(cell)
    df.columns = pd.Index([cell(c) for c in df.columns], name=df.columns.name)
    if _text_like(df.index) and not isinstance(df.index, pd.MultiIndex):
        df.index = pd.Index([cell(v) for v in df.index], name=df.index.name)
    return df
