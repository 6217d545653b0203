"""Could modal coordinates make an exact-linear integrator's set-up cheap? A measured design study.

Usage::

    python benchmarks/modal_check.py [--repeats N] [--out DIR]

``exponential_check.py`` shows that an integrator exact on each mode's linear part ``A`` (ETD2RK,
1-ms steps) is accurate, and what its core step and its matrix functions cost; the README's
budget shows that 100x against the smoothed baseline on ``engage-ramp`` then needs the set-up of
the matrix functions and the event handling to be several times cheaper than a Taylor series per
linear part and than our kernel's event handling today. One candidate: modal coordinates. One
eigen-decomposition ``A = V diag(lambda) V^-1`` per linear part gives ``e^{tau A}``,
``tau phi1(tau A)``, ``tau^2 phi2(tau A)`` for *any* ``tau`` as diagonal factors (an event's
state, a sample inside a step, a step cut to a stop: no new matrix functions), and a guard that is
linear in the state becomes a sum of exponentials in ``tau``. This script measures, for the
full-model ``engage-ramp`` and ``tip-in``, over the distinct linear parts a run visits:

1. **whether plain modal coordinates are usable**: the condition number of the eigenvector
   matrix ``V`` (the zero eigenvalues of the projected dynamics of stuck elements are defective,
   so ``V`` is singular), and the number of zero eigenvalues;
2. **a split that is**: the basis ``W = [V_nz, Z]`` (eigenvectors of the nonzero eigenvalues
   and the generalised null space, the null space of their left eigenvectors), in which ``A`` is diagonal plus a nilpotent
   block with finite-sum matrix functions (:func:`split_setup`): the condition number of ``W``
   and the largest deviation of its ``e^{hA}``, ``h phi1(hA)``, ``h phi2(hA)`` from scipy's
   ``expm`` of the augmented matrix;
3. **its set-up cost** per linear part and per run (compiled: two LAPACK ``zgeev``, an SVD and an
   inverse) against the compiled Taylor-and-doubling set-up of ``exponential_check.py``,
   interleaved.

Writes ``modal_check.json`` (default ``benchmarks/results/``) and prints a summary. Event
location and guards on the modal solution are not measured here (the open question).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_simulate import scenario_setup  # noqa: E402
from exponential_check import (  # noqa: E402
    H_MAX,
    linear_part,
    phi_blocks,
    phi_blocks_fast,
    visited_modes,
)
from results_io import write_json  # noqa: E402

from drivetrain_ctrl.simulate import SimulationOptions, simulate  # noqa: E402

#: below this |lambda h| the phi functions are summed as Taylor series (no cancellation)
_SERIES_BELOW = 0.1
#: an eigenvalue with |lambda| <= ZERO_REL * max |lambda| counts as zero: a defective zero
#: eigenvalue of multiplicity k is computed with errors of order eps^(1/k) max |lambda| (1e-5 for
#: k = 3), so the threshold must be well above that; a small nonzero eigenvalue below it is
#: handled by the block's series, whose terms then fall off as (lambda h)^k / k!
ZERO_REL = 1e-4
#: terms of the series of the small block's matrix functions (exact for a nilpotent block of
#: order <= this)
N_SERIES = 16


@nb.njit(cache=True, error_model="numpy")
def _phis(z):  # type: ignore[no-untyped-def]
    """``(e^z, phi1(z), phi2(z))`` for complex ``z`` (series near 0)."""
    if abs(z) < _SERIES_BELOW:
        p1 = 0.0j
        p2 = 0.0j
        term = 1.0 + 0.0j
        for k in range(14):
            # term = z^k / k!; phi1 = sum z^k / (k+1)!, phi2 = sum z^k / (k+2)!
            p1 += term / (k + 1)
            p2 += term / ((k + 1) * (k + 2))
            term = term * z / (k + 1)
        return np.exp(z), p1, p2
    e = np.exp(z)
    return e, (e - 1.0) / z, (e - 1.0 - z) / (z * z)


@nb.njit(cache=True, error_model="numpy")
def split_setup(A, h):  # type: ignore[no-untyped-def]
    """Modal set-up with the zero eigenvalues split off. ``A``'s eigenvalue 0 is defective in
    every mode the scenarios visit (Jordan blocks: the projected dynamics of stuck elements), so
    its eigenvectors do not form a basis. Here the basis is ``W = [V_nz, Z]``: the eigenvectors of
    the nonzero eigenvalues and an orthonormal basis ``Z`` of the generalised null space (of
    dimension ``m``, the number of zero eigenvalues; by SVD); in it ``A`` is
    ``diag(lambda_nz) (+) N`` with ``N`` nilpotent, whose matrix functions are finite sums.

    Returns ``(W, Wi, e, p1, p2, EN, P1N, P2N, m)``: the diagonal factors of the nonzero part
    (``e = e^{lambda h}``, ``p1 = h phi1``, ``p2 = h phi2``) and the ``m x m`` blocks of the
    nilpotent part. Eigenvalues below ``ZERO_REL * max |lambda|`` all go to the small block
    (``Z`` spans the null space of the left eigenvectors of the other eigenvalues, their exact
    invariant complement)."""
    n = A.shape[0]
    Ac = np.empty((n, n), dtype=np.complex128)
    for i in range(n):
        for j in range(n):
            Ac[i, j] = A[i, j]
    lam, V = np.linalg.eig(Ac)
    scale = 0.0
    for k in range(n):
        scale = max(scale, abs(lam[k]))
    m = 0
    for k in range(n):
        if abs(lam[k]) <= ZERO_REL * scale:
            m += 1
    W = np.empty((n, n), dtype=np.complex128)
    e = np.empty(n - m, dtype=np.complex128)
    p1 = np.empty(n - m, dtype=np.complex128)
    p2 = np.empty(n - m, dtype=np.complex128)
    c = 0
    for k in range(n):
        if abs(lam[k]) > ZERO_REL * scale:
            for i in range(n):
                W[i, c] = V[i, k]
            ek, a, b = _phis(lam[k] * h)
            e[c] = ek
            p1[c] = h * a
            p2[c] = h * b
            c += 1
    EN = np.eye(m, dtype=np.complex128)
    P1N = h * np.eye(m, dtype=np.complex128)
    P2N = 0.5 * h * np.eye(m, dtype=np.complex128)
    if m == 0:
        return W, np.linalg.inv(W), e, p1, p2, EN, P1N, P2N, m
    # Z: the vectors that every left eigenvector of a nonzero eigenvalue annihilates (the
    # generalised null space: not null(A^m), in which the small nonzero eigenvalues, 0.15-10 1/s
    # against 3e4 1/s, drown by round-off)
    At = np.empty((n, n), dtype=np.complex128)
    for i in range(n):
        for j in range(n):
            At[i, j] = A[j, i]
    lam_l, U = np.linalg.eig(At)
    L = np.zeros((n, n), dtype=np.complex128)
    c = 0
    for k in range(n):
        if abs(lam_l[k]) > ZERO_REL * scale and c < n - m:
            for i in range(n):
                L[c, i] = np.conj(U[i, k])
            c += 1
    _u, _s, vh = np.linalg.svd(L)
    for q in range(m):
        for i in range(n):
            W[i, n - m + q] = np.conj(vh[n - m + q, i])
    Wi = np.linalg.inv(W)
    # the nilpotent block N = (Wi A Z) restricted to the last m rows
    N = np.zeros((m, m), dtype=np.complex128)
    for r in range(m):
        for q in range(m):
            acc = 0.0j
            for i in range(n):
                wa = 0.0j
                for k in range(n):
                    wa += Wi[n - m + r, k] * A[k, i]
                acc += wa * W[i, n - m + q]
            N[r, q] = acc
    # e^{hN} = sum (hN)^k / k!, h phi1(hN) = h sum (hN)^k / (k+1)!, h phi2 = h sum (hN)^k/(k+2)!
    # (finite for a nilpotent N; N_SERIES terms for a block with small nonzero eigenvalues)
    T = np.eye(m, dtype=np.complex128)
    fact = 1.0
    for k in range(1, N_SERIES + 1):
        T = (T @ N) * h
        fact *= k
        EN += T / fact
        P1N += h * T / (fact * (k + 1))
        P2N += h * T / (fact * (k + 1) * (k + 2))
    return W, Wi, e, p1, p2, EN, P1N, P2N, m


def split_blocks(A: np.ndarray, h: float) -> tuple[np.ndarray, float, int]:
    """``[e^{hA}, h phi1(hA), h phi2(hA)]`` (n, 3n) from :func:`split_setup` (real part), the
    condition number of its basis ``W`` and the number of zero eigenvalues."""
    W, Wi, e, p1, p2, EN, P1N, P2N, m = split_setup(A, h)
    n = A.shape[0]
    blocks = []
    for d, B in ((e, EN), (p1, P1N), (p2, P2N)):
        M = np.zeros((n, n), dtype=complex)
        M[: n - m, : n - m] = np.diag(d)
        M[n - m :, n - m :] = B
        blocks.append(np.real(W @ M @ Wi))
    cond = float(np.linalg.norm(W, 2) * np.linalg.norm(Wi, 2))
    return np.hstack(blocks), cond, int(m)


def eig_cond(A: np.ndarray) -> float:
    """Condition number of the plain eigenvector matrix of ``A`` (inf when singular)."""
    _lam, V = np.linalg.eig(A)
    return float(np.linalg.cond(V))


def check_scenario(name: str, repeats: int) -> dict[str, Any]:
    setup = scenario_setup(name)
    model = setup.dt.model
    res = simulate(model, setup.x0, setup.inputs, t_end=setup.sc.t_end, options=SimulationOptions())
    visited = visited_modes(res)
    parts: dict[bytes, np.ndarray] = {}
    for mode, i in visited:
        A = linear_part(model, mode, np.asarray(res.x[i]), np.asarray(res.u[i]))
        parts.setdefault(A.tobytes(), A)
    A_list = list(parts.values())
    out: dict[str, Any] = {"nx": model.nx, "distinct_modes": len(visited)}
    out["distinct_linear_parts"] = len(A_list)

    # safety: conditioning, and agreement with scipy's expm of the augmented matrix
    plain = [eig_cond(A) for A in A_list]
    conds = []
    devs = []
    zeros = []
    for A in A_list:
        mb, cond, m = split_blocks(A, H_MAX)
        ref = phi_blocks(A, H_MAX, H_MAX)
        n = A.shape[0]
        dev = max(
            float(np.abs(mb[:, k * n : (k + 1) * n] - ref[:, k * n : (k + 1) * n]).max())
            / float(np.abs(ref[:, k * n : (k + 1) * n]).max())
            for k in range(3)
        )
        conds.append(cond)
        devs.append(dev)
        zeros.append(m)
    out["plain_eigvec_cond_min"] = min(plain)
    out["zero_eigenvalues_range"] = [min(zeros), max(zeros)]
    out["split_basis_cond_max"] = max(conds)
    out["split_basis_cond_median"] = statistics.median(conds)
    out["split_max_rel_dev_from_scipy"] = max(devs)

    # set-up cost per linear part: split modal vs Taylor and doubling, interleaved
    split_setup(A_list[0], H_MAX)
    phi_blocks_fast(A_list[0], H_MAX)
    t_split: list[float] = []
    t_taylor: list[float] = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for A in A_list:
            split_setup(A, H_MAX)
        t_split.append((time.perf_counter() - t0) / len(A_list))
        t0 = time.perf_counter()
        for A in A_list:
            phi_blocks_fast(A, H_MAX)
        t_taylor.append((time.perf_counter() - t0) / len(A_list))
    out["setup_split_s_per_part"] = statistics.median(t_split)
    out["setup_taylor_s_per_part"] = statistics.median(t_taylor)
    out["setup_taylor_over_split"] = statistics.median(
        [b / a for a, b in zip(t_split, t_taylor, strict=True)]
    )
    out["setup_split_run_s"] = out["setup_split_s_per_part"] * len(A_list)
    out["setup_taylor_run_s"] = out["setup_taylor_s_per_part"] * len(A_list)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--out", type=Path, default=HERE / "results")
    a = ap.parse_args(argv)
    if a.repeats < 1:
        ap.error(f"--repeats = {a.repeats}: must be >= 1")
    result: dict[str, Any] = {"h_max_s": H_MAX, "scenarios": {}}
    for name in ("engage-ramp", "tip-in"):
        r = check_scenario(name, a.repeats)
        result["scenarios"][name] = r
        print(f"\n=== {name} ===")
        print(
            f"{r['distinct_linear_parts']} distinct linear parts ({r['distinct_modes']} modes); "
            f"{r['zero_eigenvalues_range'][0]}-{r['zero_eigenvalues_range'][1]} zero eigenvalues, "
            f"defective: plain eigenvectors' condition number >= {r['plain_eigvec_cond_min']:.1e}"
        )
        print(
            f"split basis [V_nz, Z]: condition number max {r['split_basis_cond_max']:.2g} "
            f"(median {r['split_basis_cond_median']:.2g}); matrix functions within "
            f"{r['split_max_rel_dev_from_scipy']:.1e} of scipy's expm"
        )
        print(
            f"set-up per linear part: split modal {r['setup_split_s_per_part'] * 1e6:.1f} us, "
            f"Taylor and doubling {r['setup_taylor_s_per_part'] * 1e6:.1f} us "
            f"({r['setup_taylor_over_split']:.2f}x); all parts of a run: "
            f"{r['setup_split_run_s'] * 1e3:.2f} ms against {r['setup_taylor_run_s'] * 1e3:.2f} ms"
        )
    print()
    write_json(a.out, "modal_check.json", result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
