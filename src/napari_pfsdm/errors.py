"""The one exception class for input a user can fix.

:class:`InputError` is raised wherever the *input* is wrong (a file that is not a movie, labels
and intensity of different sizes, an unknown option value, a table without the columns a step
needs), with a message in plain words saying what was wrong and what to do. It subclasses
``ValueError``, so code that catches ``ValueError`` keeps working. The command line turns an
``InputError`` into one ``pfsdm: error: …`` line and exit status 2; any other exception is a bug
of napari-pfsdm and is reported as one (``napari_pfsdm.cli.main``).

:class:`RunFault`, an :class:`InputError`, is raised when the run could not finish for a reason
outside both the input and napari-pfsdm (a worker process killed by the system, a dask
cluster lost): the message says what happened and what to do, and the command line exits with
status 2 as for any error the user can act on.
"""

from __future__ import annotations

__all__ = ["InputError", "RunFault"]


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


class RunFault(InputError):
    """The machine or the cluster failed the run (not the input, not a bug): a worker process
    killed, the dask scheduler lost. The message says what to do (usually: run the same
    command again, which resumes).

    Examples
    --------
    >>> issubclass(RunFault, InputError)
    True
    """
