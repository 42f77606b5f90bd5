"""A run's control: the progress bar, Ctrl-C and termination signals, one-line messages.

Ctrl-C during a frame's output is held until the frame is written whole; SIGTERM and SIGHUP
raise :class:`Terminated` in the main thread so that every cleanup runs.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


class NoProgress:
    """The progress bar where none is shown (quiet, or stderr not a terminal): tqdm and the
    lock it creates are not even imported."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def progress_bar(total: int | None, quiet: bool, desc: str) -> Any:
    if quiet or not sys.stderr.isatty():
        return NoProgress()
    from tqdm import tqdm

    return tqdm(
        total=total, desc=desc, unit="frame", file=sys.stderr, leave=False, dynamic_ncols=True
    )


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a run, after the frames tracked so far were saved; the message says where."""


class Terminated(BaseException):
    """SIGTERM or SIGHUP: raised in the main thread so that every cleanup runs."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextmanager
def ctrl_c_after_block() -> Iterator[None]:
    """Ctrl-C (SIGINT) during the block is held until the block ends, then raised as
    KeyboardInterrupt: a frame's output (its rows, its video frame, the frame count) is then
    written whole or not at all. Outside the main thread the block runs as is."""
    caught: list[int] = []
    try:
        saved = signal.signal(signal.SIGINT, lambda signum, _frame: caught.append(signum))
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, saved)
    if caught:
        raise KeyboardInterrupt


@contextmanager
def termination_raises() -> Iterator[None]:
    """SIGTERM and SIGHUP raise :class:`Terminated` in the main thread for the block (so that
    ``finally`` blocks remove temporary files), instead of ending the process on the spot."""

    def raise_terminated(signum: int, _frame: object) -> None:
        raise Terminated(signum)

    saved: dict[signal.Signals, Any] = {}
    try:
        for sig in (signal.SIGTERM, signal.SIGHUP):
            saved[sig] = signal.signal(sig, raise_terminated)
    except ValueError:  # not the main thread: leave signals alone
        pass
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def one_line(err: BaseException | str) -> str:
    return " ".join(str(err).split()) or type(err).__name__
