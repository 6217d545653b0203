"""Telling the user while the simulator's kernels compile.

The first simulation in a fresh environment (an empty numba cache, or kernel sources edited)
compiles the kernels, which takes minutes on a laptop; later processes load the machine code
from numba's cache in about a second. A library call must not print, so :func:`announce_compile`
logs the fact once per process (logger ``drivetrain_ctrl``, level WARNING so that it shows
without any logging set-up); the command line and the warm-up show a one-line notice with the
elapsed time instead (:func:`compile_progress`).
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

from .. import kernels as K

__all__ = ["EXPECTED_COMPILE_S", "kernels_ready", "announce_compile", "compile_progress"]

logger = logging.getLogger("drivetrain_ctrl")

#: typical compile time of the simulator kernels with an empty cache on two cores [s]
#: (``benchmarks/bench_first_call.py``; the docs' performance page has the current figure)
EXPECTED_COMPILE_S: float = 100.0

_announced = False


def kernels_ready() -> bool:
    """True if the simulator kernel needs no compilation in this process (compiled already, or
    in numba's on-disk cache for this machine)."""
    return K.is_cached(K.simulate_kernel)


def _message() -> str:
    return (
        "compiling the simulator kernels: the first run with an empty numba cache takes about "
        f"{EXPECTED_COMPILE_S:.0f} s on two cores; later processes load them in about a second"
    )


def announce_compile() -> None:
    """Log once per process, before the simulator compiles, that it is compiling (nothing when
    the kernels are cached, or after :func:`compile_progress` has shown its notice)."""
    global _announced
    if _announced or kernels_ready():
        return
    _announced = True
    logger.warning("drivetrain_ctrl: %s", _message())


@contextmanager
def compile_progress(stream: TextIO | None = None, *, interval: float = 1.0) -> Iterator[None]:
    """Show a one-line notice on ``stream`` (default stderr) while the body compiles the
    kernels: the expected duration, then the elapsed seconds (updated in place every
    ``interval`` seconds on a terminal) and the time it took. Shows nothing when the kernels
    are cached."""
    global _announced
    if kernels_ready():
        yield
        return
    _announced = True  # the notice replaces the library's log line
    out = sys.stderr if stream is None else stream
    tty = bool(getattr(out, "isatty", lambda: False)())
    head = f"[drivetrain-ctrl] {_message()} ..."
    print(head, end="" if tty else "\n", file=out, flush=True)
    stop = threading.Event()
    tic = time.perf_counter()

    def tick() -> None:
        while not stop.wait(interval):
            elapsed = time.perf_counter() - tic
            print(f"\r{head} {elapsed:.0f} s", end="", file=out, flush=True)

    ticker = threading.Thread(target=tick, daemon=True) if tty else None
    if ticker is not None:
        ticker.start()
    try:
        yield
    finally:
        stop.set()
        if ticker is not None:
            ticker.join()
        done = f"compiled in {time.perf_counter() - tic:.0f} s"
        print(f"\r{head} {done}" if tty else f"[drivetrain-ctrl] {done}", file=out, flush=True)
