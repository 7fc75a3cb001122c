"""Exception types shared by every layer (imports nothing from the package).

:class:`UserError` is a problem with what the user gave (a file, an option, a setting,
an argument of a library call): the command line prints its one-line message and exits
with status 2. Anything else that reaches the command line is a bug in continuum-mhe;
it says so and exits with status 70 (``EX_SOFTWARE``).
"""

from __future__ import annotations


class UserError(ValueError):
    """A problem with user input or settings; the message is one line saying what is
    wrong and, where known, where (``FILE: line N: ...``) and the likely cause.

    A subclass of :class:`ValueError`, so library callers that catch ``ValueError``
    keep working."""


class UnobservableShapeWarning(UserWarning):
    """The robot's IMUs cannot determine its shape (fewer independent tilt readings
    than bend coordinates): every estimate of it is ``uncertain``."""
