"""The design studies' own numerics (``benchmarks/modal_check.py``), on matrices whose matrix
functions are known: a study that quotes a deviation from scipy must compute what it claims."""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import numpy as np
from scipy.linalg import expm


def _phi_blocks_scipy(A: np.ndarray, h: float) -> np.ndarray:
    """``[e^{hA}, h phi1(hA), h phi2(hA)]`` from the augmented matrix (independent of the
    studies' code)."""
    n = A.shape[0]
    M = np.zeros((3 * n, 3 * n))
    M[:n, :n] = A
    M[:n, n : 2 * n] = np.eye(n)
    M[n : 2 * n, 2 * n :] = np.eye(n)
    E = expm(h * M)[:n, :]
    return np.hstack([E[:, :n], E[:, n : 2 * n], E[:, 2 * n :] / h])


def test_split_setup_handles_a_defective_zero_eigenvalue(
    bench: Callable[[str], ModuleType],
) -> None:
    mc = bench("modal_check")
    # a free body with a position state (Jordan block at 0), a lightly damped stiff mode, a slow
    # real mode and a lag: eigenvectors of the plain decomposition are singular
    A = np.zeros((6, 6))
    A[1, 0] = 1.0  # position' = speed; speed' = 0
    A[2:4, 2:4] = [[0.0, 1.0], [-(3500.0**2), -2 * 0.03 * 3500.0]]
    A[4, 4] = -0.15
    A[5, 5] = -10.0
    A[2, 5] = 750.0  # the lag drives the stiff mode
    A[0, 3] = 0.5  # and the stiff mode the free body
    h = 1e-3
    assert mc.eig_cond(A) > 1e12  # defective: plain modal coordinates fail
    blocks, cond, m = mc.split_blocks(A, h)
    # the double zero eigenvalue and the slow -0.15 (below ZERO_REL * 3500) go to the series block
    assert m == 3
    assert cond < 1e4
    ref = _phi_blocks_scipy(A, h)
    for k in range(3):
        r = ref[:, 6 * k : 6 * (k + 1)]
        got = blocks[:, 6 * k : 6 * (k + 1)]
        assert np.abs(got - r).max() <= 1e-9 * np.abs(r).max(), k
    # and the exact solution of x' = A x + F0 + (t/h) dF at h from them
    x0 = np.array([1.0, 0.0, 0.01, -2.0, 3.0, 0.5])
    F0 = np.array([0.2, 0.0, 5.0, 0.0, -1.0, 0.0])
    dF = np.array([0.0, 0.0, 1.0, 0.0, 0.3, 0.0])
    x1 = blocks @ np.concatenate([x0, F0, dF])
    n = 6
    # x' = A x + F0 + (t/h) dF as an autonomous system with states [x, 1, t]
    Maug = np.zeros((n + 2, n + 2))
    Maug[:n, :n] = A
    Maug[:n, n] = F0
    Maug[:n, n + 1] = dF / h
    Maug[n + 1, n] = 1.0
    w = expm(h * Maug) @ np.concatenate([x0, [1.0, 0.0]])
    assert np.abs(x1 - w[:n]).max() <= 1e-9 * np.abs(w[:n]).max()
