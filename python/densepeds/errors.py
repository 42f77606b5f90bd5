"""Exceptions for user-facing mistakes. The CLI prints their message on one line and exits 2."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator


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


class InputWarning(UserWarning):
    """Input that is dropped or reinterpreted rather than refused (detections past the sequence's
    end, boxes outside the declared image, frames of another size). Never silent: the CLI prints
    each on one line of stderr."""


def warn_input(message: str) -> None:
    """Warn (:class:`InputWarning`) that some input is dropped or reinterpreted."""
    import warnings

    warnings.warn(message, InputWarning, stacklevel=2)


@contextlib.contextmanager
def warnings_as_lines(prefix: str) -> Iterator[None]:
    """Within the block, each :class:`InputWarning` is one line ``PREFIX: warning: ...`` on stderr
    (every time, not once per place)."""
    import sys
    import warnings

    def show(message: Warning | str, category: type[Warning], *rest: object, **kw: object) -> None:
        if issubclass(category, InputWarning):
            sys.stderr.write(f"{prefix}: warning: {' '.join(str(message).split())}\n")
        else:
            original(message, category, *rest, **kw)  # type: ignore[arg-type]

    with warnings.catch_warnings():
        warnings.simplefilter("always", InputWarning)
        original = warnings.showwarning
        warnings.showwarning = show  # type: ignore[assignment]
        yield
