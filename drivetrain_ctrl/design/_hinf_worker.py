"""The H-infinity gamma iteration of :mod:`drivetrain_ctrl.design.hinf`, run in a child process.

It needs numpy and slycot only, so that it also runs as a script (``python -I _hinf_worker.py``,
the augmented plant pickled on stdin, the result on stdout) without importing the package: the
launch used where ``fork`` is not available or the caller is a daemonic process (a Dask or
``multiprocessing`` pool worker, which may not start ``multiprocessing`` children).
"""

from __future__ import annotations

import pickle
import sys
from typing import Any

import numpy as np


def gamma_iteration(A: Any, B: Any, C: Any, D: Any, backoff: float) -> tuple[Any, ...]:
    """slycot ``sb10ad``'s gamma iteration (``job=3``, bisection then scanning, as
    python-control's ``hinfsyn``) on the augmented plant ``(A, B, C, D)`` (one measurement, one
    control input, the last row and column), started at the first of 1, 10, 100, ... that admits
    a controller (``job=4``; ``hinfsyn`` starts at 1e100, which costs many more iterations), then
    the central controller at ``(1 + backoff) gamma_opt`` (``job=4``; backed off further if that
    fails numerically). Returns ``("ok", gamma_opt, gamma, (Ak, Bk, Ck, Dk), rcond)``; raises
    slycot's error otherwise."""
    import slycot

    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    g0 = 1e100
    for g in 10.0 ** np.arange(0, 13):
        try:
            slycot.sb10ad(n, m, p, 1, 1, float(g), A, B, C, D, job=4)
        except Exception:  # not admissible at this gamma (or a numerical failure): go up
            continue
        g0 = float(g)
        break
    gam_opt = float(slycot.sb10ad(n, m, p, 1, 1, g0, A, B, C, D, job=3)[0])
    f = 1.0 + backoff
    last: Exception | None = None
    for _ in range(6):
        try:
            out = slycot.sb10ad(n, m, p, 1, 1, gam_opt * f, A, B, C, D, job=4)
            return ("ok", gam_opt, gam_opt * f, tuple(out[1:5]), out[9])
        except Exception as exc:  # numerical trouble close to the optimum: back off more
            last = exc
            f = 1.0 + 2.0 * (f - 1.0)
    raise last if last is not None else RuntimeError("sb10ad failed")


def run(args: tuple[Any, ...]) -> tuple[Any, ...]:
    """:func:`gamma_iteration` with every failure turned into ``("error", type name, message,
    slycot info)``."""
    try:
        return gamma_iteration(*args)
    except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
        return ("error", type(exc).__name__, str(exc), getattr(exc, "info", None))


def main() -> None:
    """Script entry: the arguments pickled on stdin, the result pickled on stdout."""
    args = pickle.load(sys.stdin.buffer)
    pickle.dump(run(args), sys.stdout.buffer)
    sys.stdout.buffer.flush()


if __name__ == "__main__":
    main()
