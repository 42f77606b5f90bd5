"""``python -m densepeds`` and the ``densepeds`` command: see densepeds.cli.

Ctrl-C while the command's modules load (numpy, OpenCV, onnxruntime: a few tenths of a second)
ends it with one line and status 130, as Ctrl-C does later, instead of an import traceback.
"""

from __future__ import annotations

import os
import signal
import sys


def _interrupted_while_loading(_signum: int, _frame: object) -> None:
    sys.stderr.write("densepeds: interrupted\n")
    sys.stderr.flush()
    os._exit(130)


def run() -> int:
    try:
        saved = signal.signal(signal.SIGINT, _interrupted_while_loading)
    except ValueError:  # not the main thread
        saved = None
    try:
        from densepeds.cli import main
    finally:
        if saved is not None:
            signal.signal(signal.SIGINT, saved)
    try:
        return main()
    except KeyboardInterrupt:  # raised after main() wrote its one line: the same exit status
        return 130


if __name__ == "__main__":
    sys.exit(run())
