"""The project's errors: one base class, so callers can catch everything besman raises for bad input.

Every error besman raises for bad input or an impossible request is a :class:`BesmanError`; it is a
``ValueError``, so code that catches ``ValueError`` keeps working.
"""


class BesmanError(ValueError):
    """Bad input or an impossible request; the message names the file, field or value and says why."""


class InputError(BesmanError):
    """An argument is malformed or out of range (the message names it)."""


class ArgumentTypeError(InputError, TypeError):
    """An argument of the wrong type (the message names the function, the argument, the value and the type
    expected). Also a ``TypeError``, as Python's own would be."""


class UnknownNameError(InputError, KeyError):
    """A name (of a joint group, arm, object, task...) that does not exist; the message lists the valid
    ones. Also a ``KeyError``, as a failed lookup by name."""

    __str__ = Exception.__str__  # the message as written (a KeyError would quote it)


class PluginWarning(UserWarning):
    """An installed plugin (another distribution's entry point) that besman leaves out; the message names
    the distribution and why. The command line prints it as one line."""
