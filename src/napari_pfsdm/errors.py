"""The one exception class for input a user can fix.

:class:`InputError` is raised wherever the *input* is wrong (a file that is not a movie, labels
and intensity of different sizes, an unknown option value, a table without the columns a step
needs), with a message in plain words saying what was wrong and what to do. It subclasses
``ValueError``, so code that catches ``ValueError`` keeps working. The command line turns an
``InputError`` into one ``pfsdm: error: …`` line and exit status 2; any other exception is a bug
of napari-pfsdm and is reported as one (``napari_pfsdm.cli.main``).
"""

from __future__ import annotations

__all__ = ["InputError"]


class InputError(ValueError):
    """Input the user can fix: the message says what was wrong and what to do.

    Examples
    --------
    >>> try:
    ...     raise InputError("mapping must be one of harmonic, bijective, radial; got 'x'")
    ... except ValueError as exc:  # an InputError is a ValueError
    ...     print(type(exc).__name__, "-", exc)
    InputError - mapping must be one of harmonic, bijective, radial; got 'x'
    """
