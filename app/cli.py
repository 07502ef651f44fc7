"""What every command line of the project shares: bad input is one line on stderr and exit status 2.

    parser = OneLineParser(prog="python -m app.x", description=...)
    parser.add_argument("--rate", type=number(0.1, 100.0, "Hz"), ...)
    ...
    if __name__ == "__main__":
        sys.exit(run_cli(main, "python -m app.x"))

``OneLineParser`` prints ``prog: error: message`` (no usage block) and exits 2; its sub-parsers inherit
that. ``number`` is an argparse type that refuses non-numbers, NaN/inf and values outside a range,
naming the range. ``run_cli`` runs ``main`` and turns the errors bad input raises on the way — a file
that cannot be read or written (``OSError``), an invalid file (``AppError``, e.g. ``ConfigError``), a
value no parser caught (``ValueError``) — into that one line and exit status 2, never a traceback;
output piped into ``head`` stops quietly. ``handle_signals_in_thread`` runs what a signal should do in a
thread of its own, never inside the signal handler.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Collection, Mapping
from pathlib import Path
from typing import NoReturn

from app.errors import AppError

BAD_INPUT = 2


class OneLineParser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        self.exit(BAD_INPUT, f"{self.prog}: error: {message}\n")


def number(lo: float, hi: float, unit: str = "", kind: type[float] | type[int] = float) -> Callable[[str], float]:
    """An argparse type: a finite ``kind`` in ``lo..hi`` (``unit`` only names it in the message)."""

    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a{'n integer' if kind is int else ' number'}") from None
        if not (math.isfinite(value) and lo <= value <= hi):
            raise argparse.ArgumentTypeError(f"{text} is outside {lo:g}..{hi:g} {unit}".rstrip())
        return value

    return parse


def int_list(lo: int, hi: int) -> Callable[[str], tuple[int, ...]]:
    """An argparse type: comma-separated integers in ``lo..hi`` (e.g. sea states ``0,1,3``)."""

    def parse(text: str) -> tuple[int, ...]:
        try:
            values = tuple(int(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of integers") from None
        if not all(lo <= v <= hi for v in values):
            raise argparse.ArgumentTypeError(f"{text}: each must be in {lo}..{hi}")
        return values

    return parse


def number_list(lo: float, hi: float, unit: str = "") -> Callable[[str], tuple[float, ...]]:
    """An argparse type: comma-separated finite numbers, each in ``lo..hi`` (e.g. drift speeds ``0,0.9``)."""
    one = number(lo, hi, unit)

    def parse(text: str) -> tuple[float, ...]:
        return tuple(one(v) for v in text.split(","))

    return parse


def name_list(names: Collection[str]) -> Callable[[str], tuple[str, ...]]:
    """An argparse type: distinct comma-separated names, each one of ``names``."""

    def parse(text: str) -> tuple[str, ...]:
        values = tuple(n.strip() for n in text.split(","))
        if any(n not in names for n in values) or len(set(values)) != len(values):
            raise argparse.ArgumentTypeError(
                f"{text!r}: give distinct names from {', '.join(sorted(names))}, comma-separated"
            )
        return values

    return parse


def run_child(cmd: list[str], cwd: Path) -> None:
    """Run another of our command lines; its failure becomes an ``AppError`` carrying its one-line error."""
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
        raise AppError(f"{' '.join(cmd[1:3])} failed: {last}")


def one_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        name = exc.filename2 or exc.filename  # symlink/rename: the second name is the one being made
        return f"{name}: {exc.strerror}" if name else exc.strerror
    return " ".join(str(exc).split()) or type(exc).__name__


def run_cli(main: Callable[[], int], prog: str) -> int:
    """``main()``'s exit status; bad input it raises becomes one line on stderr and status 2."""
    try:
        return main()
    except BrokenPipeError:  # piped into head: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (AppError, OSError, ValueError) as e:
        print(f"{prog}: error: {one_line(e)}", file=sys.stderr)
        return BAD_INPUT


def handle_signals_in_thread(handlers: Mapping[signal.Signals, Callable[[], None]]) -> None:
    """On each of ``handlers``' signals, run its handler in a thread of its own (``signals``), not in the handler.

    A Python signal handler runs in the main thread between two bytecodes, wherever that thread is: also while it
    holds a lock, and also inside the same handler when the signal comes again. A handler that takes a lock
    (``Event.set`` does) can then wait forever for itself. It happened: Linux sends a child its parent-death signal
    once for every thread of the dying parent (the child is handed from thread to thread), and a simulator whose
    app was killed outright hung in ``Event.set`` four handlers deep. The handler here only writes the signal's
    number to a pipe (a system call, no lock); the thread reads it and calls the handler. Call from the main thread.
    """
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)

    def on_signal(signum: int, frame: object) -> None:
        with contextlib.suppress(BlockingIOError):  # the pipe is full: the thread has plenty to do already
            os.write(write_fd, bytes([signum]))

    def dispatch() -> None:
        while data := os.read(read_fd, 64):
            for signum in data:
                handlers[signal.Signals(signum)]()

    threading.Thread(target=dispatch, name="signals", daemon=True).start()
    for signum in handlers:
        signal.signal(signum, on_signal)
