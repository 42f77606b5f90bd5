"""Exceptions for user-facing mistakes. The CLI prints their message on one line and exits 2."""


class DensePedsError(Exception):
    """Base class: a problem with the user's input, options or models (not a bug)."""


class InputError(DensePedsError, ValueError):
    """Unreadable or malformed input: missing file, corrupt video, bad det file, bad frame range,
    or arrays of the wrong shape, dtype or values (a ValueError, as numpy and scipy raise)."""


class DetFileError(InputError):
    """A MOTChallenge det/gt/tracks text file that cannot be parsed."""


class ModelError(DensePedsError):
    """A model file that is missing or does not have the expected input/output contract."""


class ParameterError(DensePedsError, ValueError):
    """An option value outside its allowed range or set."""


class OutputError(DensePedsError):
    """An output that cannot be written completely: permissions, a full disk, a path in a file."""
