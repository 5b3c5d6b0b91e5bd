"""The one carrier of a feature table's options: ``table.attrs["pfsdm"]``, through helpers.

A feature table needs the options it was measured with (the rings' weights, N_F, …) to be
compared or projected correctly. They travel with the pandas table in ``DataFrame.attrs``,
which pandas keeps through some operations (selection, sorting, copying) and drops or trips
over in others (``merge``; ``concat`` compares the inputs' attrs and fails on numpy arrays).
Every producer of a table in the package goes through these helpers instead of touching
``attrs`` by hand (``tests/test_layering.py`` holds that outside this module and the CSV
files' reader and writer no code assigns ``.attrs``); on disk the options live in the CSV's
JSON sidecar (:mod:`napari_pfsdm.io`).

The helpers take and return pandas DataFrames but import nothing: the core stays free of
pandas.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

__all__ = ["OPTIONS_KEY", "carry_options", "concat_tables", "keeping_options", "plain",
           "set_options", "table_options"]

#: The ``attrs`` key of the options.
OPTIONS_KEY = "pfsdm"


def table_options(table: Any) -> dict[str, Any]:
    """A copy of the options ``table`` carries (``{}`` when it carries none)."""
    return dict(getattr(table, "attrs", {}).get(OPTIONS_KEY) or {})


def set_options(table: Any, options: Mapping[str, Any] | None) -> Any:
    """Give ``table`` these options (in place, replacing any); returns ``table``.

    Examples
    --------
    >>> import pandas as pd
    >>> t = set_options(pd.DataFrame({"frame": [0]}), {"n_fourier": 6})
    >>> table_options(t)
    {'n_fourier': 6}
    """
    table.attrs[OPTIONS_KEY] = dict(options or {})
    return table


def carry_options(source: Any, result: Any) -> Any:
    """``result`` with the same attrs (options and all) as ``source``, in place; returns it.
    For a table made from another by an operation that drops them (merge, insert, concat)."""
    result.attrs = {k: (dict(v) if isinstance(v, dict) else v)
                    for k, v in getattr(source, "attrs", {}).items()}
    return result


def plain(table: Any) -> Any:
    """A copy of ``table`` without attrs: what pandas writes to a file or compares."""
    out = table.copy()
    out.attrs = {}
    return out


def keeping_options(table: Any, operation: Callable[[Any], Any]) -> Any:
    """``operation(table)`` run on a copy without attrs, its result given ``table``'s attrs.

    Examples
    --------
    >>> import pandas as pd
    >>> t = set_options(pd.DataFrame({"frame": [0], "label": [1]}), {"n_radii": 8})
    >>> right = pd.DataFrame({"label": [1], "group": ["a"]})
    >>> out = keeping_options(t, lambda df: df.merge(right, on="label"))
    >>> list(out.columns), table_options(out)
    (['frame', 'label', 'group'], {'n_radii': 8})
    """
    return carry_options(table, operation(plain(table)))


def concat_tables(tables: Iterable[Any], **kwargs: Any) -> Any:
    """``pandas.concat`` of tables measured with the same options: the result carries the
    first table's attrs (pandas would compare every input's, which fails on numpy arrays)."""
    import pandas as pd

    tables = list(tables)
    out = pd.concat([plain(t) for t in tables], **kwargs)
    return carry_options(tables[0], out) if tables else out
