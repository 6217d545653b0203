"""Would an integrator that is exact on each mode's linear part pay? A measured design study.

Usage::

    python benchmarks/exponential_check.py [--repeats N] [--out DIR]

Our kernel (Dormand-Prince 5(4)) takes 6600-8400 steps on a 3-s full-model run; at ``h_max`` =
1 ms a run needs at least 3000. Within one mode the drivetrain is ``x' = A x + c + N(x)``: ``A``
is the mode's linear part (springs, dampers, gear mesh; ``Model.jacobian`` at the mode's entry),
``c`` the inputs and kinetic friction torques, ``N`` the weak nonlinear rest (quadratic drag,
table slopes). An exponential integrator takes ``A`` exactly, so only ``N`` and ``h_max`` limit
its steps. This script measures, for the full-model ``engage-ramp`` and ``tip-in``, the parts
that decide whether such an integrator would reach the smoothed-baseline goal:

1. **accuracy** of the second-order exponential Runge-Kutta method (ETD2RK, Cox-Matthews) on
   the longest one-mode segment at h = 1, 0.5 ms, against scipy DOP853 at rtol 1e-12 in that
   mode; with two right-hand sides per step, and with one (the stage ``F(a)`` reused as the next
   step's ``F(x0)``);
2. **core cost per step** (our right-hand side inlined, as in the kernel, plus the matrix-vector
   products; no guards, events, energy or recording) against our kernel's cost per step on the
   whole run, both measured here;
3. **set-up cost per mode**: the matrix functions ``e^{hA}``, ``h phi1(hA)``, ``h phi2(hA)``
   (scipy ``expm`` of a 3n x 3n block matrix, and a compiled Taylor series with doubling,
   checked against it), and how many distinct modes and linear parts a run visits;
4. **energy quadrature**: the dissipated energies on the segment by Gauss-Legendre with m nodes
   per 1-ms step on the method's exact-in-A continuous extension, against the reference, as a
   share of the run's energy budget ``1e-6 max(W_in, max E_stored)`` (the residual goal);
5. the consequence: a lower bound of a run's time (3000 core steps plus set-up of every mode,
   guards, events, energy and recording not counted) and of its speedup over the smoothed
   baseline (``bench_simulate.run_tanh``, timed here).

Writes ``exponential_check.json`` (default ``benchmarks/results/``) and prints a summary.

What a simulator of this kind would still need (a proposal, not measured here): matrix functions
cached per distinct linear part (a hash of ``A``), with the half-step ones from the doubling for
a midpoint sample; guards and dissipated powers at the midpoint and the step end (Simpson's rule,
one order below the 2-point Gauss measured here); event location on a Taylor polynomial of the
fired guard about the nearest sample (the derivatives ``c^T M^k w`` of the augmented system
``w' = M w``, ``w = [x; F0; dF]``) and the state at the event from the same series; steps cut to
stop times with uncached matrix functions; error control on the second-order correction with a
ladder of halved steps. Closed-loop controllers and smoothed friction would stay on
Dormand-Prince.
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
from scipy.integrate import solve_ivp
from scipy.linalg import expm

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_simulate import run_tanh, scenario_setup  # noqa: E402
from order_check import longest_segment  # noqa: E402
from results_io import write_json  # noqa: E402

from drivetrain_ctrl import kernels as K  # noqa: E402
from drivetrain_ctrl.model import Mode  # noqa: E402
from drivetrain_ctrl.simulate import SimulationOptions, simulate  # noqa: E402

H_MAX = 1e-3


def phi_blocks(A: np.ndarray, tau: float, h: float) -> np.ndarray:
    """``[e^{tau A}, tau phi1(tau A), tau^2/h phi2(tau A)]`` (n, 3n): the exact solution at
    ``tau`` of ``x' = A x + F0 + (t/h) dF`` is this times ``[x0; F0; dF]``."""
    n = A.shape[0]
    M = np.zeros((3 * n, 3 * n))
    M[:n, :n] = A
    M[:n, n : 2 * n] = np.eye(n)
    M[n : 2 * n, 2 * n :] = np.eye(n) / h
    return np.ascontiguousarray(expm(tau * M)[:n, :])


@nb.njit(cache=True, error_model="numpy")
def _matmul(X, Y, out):  # type: ignore[no-untyped-def]
    n = X.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = 0.0
        for k in range(n):
            xik = X[i, k]
            for j in range(n):
                out[i, j] += xik * Y[k, j]


@nb.njit(cache=True, error_model="numpy")
def phi_blocks_fast(A, h):  # type: ignore[no-untyped-def]
    """:func:`phi_blocks` ``(A, h, h)`` without scipy: Taylor series of ``e^{tau A}``,
    ``tau phi1(tau A)``, ``tau^2 phi2(tau A)`` at ``tau = h / 2^s`` with ``||tau A||_1 <= 1/2``
    (degree 16: truncation below 1e-19), then ``s`` doublings ``E <- E^2``,
    ``P1 <- (I + E) P1``, ``Psi <- (I + E) Psi + tau P1``, three matrix products each."""
    n = A.shape[0]
    nrm = 0.0
    for j in range(n):
        c = 0.0
        for i in range(n):
            c += abs(A[i, j])
        nrm = max(nrm, c)
    s = 0
    while nrm * h / 2.0**s > 0.5:
        s += 1
    tau = h / 2.0**s
    X = A * tau
    E = np.eye(n)
    P1 = np.eye(n)
    Psi = 0.5 * np.eye(n)
    T = np.eye(n)
    W = np.empty((n, n))
    for k in range(1, 17):
        _matmul(T, X, W)
        for i in range(n):
            for j in range(n):
                t = W[i, j] / k
                T[i, j] = t
                E[i, j] += t
                P1[i, j] += t / (k + 1)
                Psi[i, j] += t / ((k + 1) * (k + 2))
    P1 *= tau
    Psi *= tau * tau
    IE = np.empty((n, n))
    for _ in range(s):
        for i in range(n):
            for j in range(n):
                IE[i, j] = E[i, j] + (1.0 if i == j else 0.0)
        _matmul(IE, Psi, W)
        for i in range(n):
            for j in range(n):
                Psi[i, j] = W[i, j] + tau * P1[i, j]
        _matmul(IE, P1, W)
        P1[:, :] = W
        _matmul(E, E, W)
        E[:, :] = W
        tau *= 2.0
    out = np.empty((n, 3 * n))
    out[:, :n] = E
    out[:, n : 2 * n] = P1
    out[:, 2 * n :] = Psi / h
    return out


@nb.njit(cache=True, error_model="numpy")
def _matvec3(E, x, F0, dF, out):  # type: ignore[no-untyped-def]
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for k in range(n):
            acc += E[i, k] * x[k] + E[i, n + k] * F0[k] + E[i, 2 * n + k] * dF[k]
        out[i] = acc


@nb.njit(cache=True, error_model="numpy", inline="always")
def _forcing(D, A, x, u, fm, reg, PT, f, tau, pd, out):  # type: ignore[no-untyped-def]
    """``out = f(x) - A x``: the inputs, kinetic friction torques and nonlinear rest
    ``F(x) = c + N(x)`` (our right-hand side inlined, as in the kernel; ``f`` work array)."""
    K.rhs_into(D, x, u, fm, reg, PT, f, tau, pd, 0, False)
    n = x.shape[0]
    for i in range(n):
        acc = f[i]
        for k in range(n):
            acc -= A[i, k] * x[k]
        out[i] = acc


@nb.njit(cache=True, error_model="numpy")
def etd2_run(D, E, A, x0, u, fm, reg, PT, nsteps, two_rhs):  # type: ignore[no-untyped-def]
    """ETD2RK with fixed step and fixed mode; ``E`` = phi_blocks(A, h, h). Returns the end state
    and the largest second-order correction (an error estimate of the first-order stage).
    ``two_rhs``: evaluate ``F`` at each step's end; else reuse the stage's ``F(a)`` there."""
    n = x0.shape[0]
    x = x0.copy()
    a = np.empty(n)
    f = np.empty(n)
    F0 = np.empty(n)
    dF = np.zeros(n)
    zero = np.zeros(n)
    tau = np.empty(D.M.shape[0])
    pd = np.empty(1)
    _forcing(D, A, x, u, fm, reg, PT, f, tau, pd, F0)
    corr = 0.0
    for _ in range(nsteps):
        _matvec3(E, x, F0, zero, a)
        _forcing(D, A, a, u, fm, reg, PT, f, tau, pd, dF)
        for i in range(n):
            dF[i] -= F0[i]
        for i in range(n):
            acc = 0.0
            for k in range(n):
                acc += E[i, 2 * n + k] * dF[k]
            x[i] = a[i] + acc
            if abs(acc) > corr:
                corr = abs(acc)
        if two_rhs:
            _forcing(D, A, x, u, fm, reg, PT, f, tau, pd, F0)
        else:
            for i in range(n):
                F0[i] += dF[i]
    return x, corr


def linear_part(model: Any, mode: Mode, x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The mode's linear part: the Jacobian without the smooth nonlinear terms (drag, table
    slopes, capacity-vs-input), which depends on the mode only, not on ``x``, ``u``."""
    fm, reg = mode.arrays()
    P, _ = K.mode_matrices(model.data, fm)
    return np.asarray(K.jacobians(model.data, x, u, fm, reg, P, True)[0])


def visited_modes(res: Any) -> list[tuple[Mode, int]]:
    """The distinct modes (friction modes and table segments) a run's samples hold, each with the
    index of its first sample."""
    keys = np.concatenate([np.asarray(res.fm), np.asarray(res.reg)], axis=1)
    _uniq, first = np.unique(keys, axis=0, return_index=True)
    return [
        (Mode(tuple(int(v) for v in res.fm[i]), tuple(int(v) for v in res.reg[i])), int(i))
        for i in first
    ]


def gauss_dissipation(
    model: Any, mode: Mode, u: np.ndarray, A: np.ndarray, x0: np.ndarray, T: float, m: int
) -> np.ndarray:
    """Dissipated energies [J] over ``[0, T]``: ETD2 steps of ``H_MAX`` (two right-hand sides),
    Gauss-Legendre with ``m`` nodes per step on the continuous extension."""
    ns = int(round(T / H_MAX))
    h = T / ns
    E = phi_blocks(A, h, h)
    nodes, weights = np.polynomial.legendre.leggauss(m)
    th = 0.5 * (nodes + 1.0)
    En = [phi_blocks(A, s * h, h) for s in th]
    n = A.shape[0]

    def F(x: np.ndarray) -> np.ndarray:
        return model.rhs(x, u, mode) - A @ x

    x = x0.copy()
    out = np.zeros(len(model.power_names()))
    for _ in range(ns):
        F0 = F(x)
        a = E[:, :n] @ x + E[:, n : 2 * n] @ F0
        dF = F(a) - F0
        for Ek, w in zip(En, weights, strict=True):
            xk = Ek @ np.concatenate([x, F0, dF])
            out += 0.5 * h * w * np.array(list(model.powers(xk, u, mode)[1].values()))
        x = a + E[:, 2 * n :] @ dF
    return out


def reference_dissipation(sol: Any, model: Any, mode: Mode, u: np.ndarray, T: float) -> np.ndarray:
    """Dissipated energies [J] on the reference's dense output: Gauss-Legendre, 8 nodes per 50 us."""
    nodes, weights = np.polynomial.legendre.leggauss(8)
    edges = np.linspace(0.0, T, int(np.ceil(T / 5e-5)) + 1)
    out = np.zeros(len(model.power_names()))
    for t0, t1 in zip(edges[:-1], edges[1:], strict=True):
        ts = 0.5 * (t1 - t0) * nodes + 0.5 * (t1 + t0)
        xs = sol.sol(ts)
        for k in range(ts.size):
            p = np.array(list(model.powers(xs[:, k], u, mode)[1].values()))
            out += 0.5 * (t1 - t0) * weights[k] * p
    return out


def median_time(fn: Any, repeats: int) -> float:
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def check_scenario(name: str, repeats: int) -> dict[str, Any]:
    setup = scenario_setup(name)
    params, sc, dtr, x0_run, inputs, fast = setup
    model = dtr.model
    opts = SimulationOptions()
    res = simulate(model, x0_run, inputs, t_end=sc.t_end, options=opts)
    out: dict[str, Any] = {"nx": model.nx, "steps_ours": int(res.stats["steps"])}

    # distinct modes, and the set-up cost of each one's matrix functions
    visited = visited_modes(res)
    out["distinct_modes"] = len(visited)
    A_list = []
    lin_keys = set()
    for mode, i in visited:
        A_list.append(model.jacobian(np.asarray(res.x[i]), np.asarray(res.u[i]), mode)[0])
        lin_keys.add(linear_part(model, mode, np.asarray(res.x[i]), np.asarray(res.u[i])).tobytes())
    # modes that differ only in what the linear part leaves out (capacity-table pieces, slip
    # directions through the forcing) could share one set of matrix functions
    out["distinct_linear_parts"] = len(lin_keys)
    t0 = time.perf_counter()
    for A in A_list:
        phi_blocks(A, H_MAX, H_MAX)
    out["setup_s_per_mode"] = (time.perf_counter() - t0) / len(A_list)
    # the same without scipy (compiled; its agreement with scipy is checked here)
    phi_blocks_fast(A_list[0], H_MAX)
    dev = max(
        float(
            np.abs(phi_blocks_fast(A, H_MAX) - phi_blocks(A, H_MAX, H_MAX)).max()
            / np.abs(phi_blocks(A, H_MAX, H_MAX)).max()
        )
        for A in A_list
    )
    t0 = time.perf_counter()
    for _ in range(repeats):
        for A in A_list:
            phi_blocks_fast(A, H_MAX)
    out["setup_fast_s_per_mode"] = (time.perf_counter() - t0) / (repeats * len(A_list))
    out["setup_fast_max_rel_dev_from_scipy"] = dev

    # the longest one-mode segment
    i, j = longest_segment(res)
    mode = Mode(tuple(int(v) for v in res.fm[i]), tuple(int(v) for v in res.reg[i]))
    u = np.asarray(res.u[i])
    if np.ptp(np.asarray(res.u[i : j + 1]), axis=0).max() > 0.0:
        raise RuntimeError(f"{name}: inputs vary on the longest segment")
    x0 = np.asarray(res.x[i])
    T = float(res.t[j] - res.t[i])
    out["segment"] = {"t0_s": float(res.t[i]), "duration_s": T, "steps_ours": int(j - i)}
    sol = solve_ivp(
        lambda _t, x: model.rhs(x, u, mode),
        (0.0, T),
        x0,
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        dense_output=True,
    )
    x_ref = sol.y[:, -1]
    A, _ = model.jacobian(x0, u, mode)
    out["segment"]["max_abs_eigenvalue_1_s"] = float(np.abs(np.linalg.eigvals(A)).max())
    fm, reg = mode.arrays()
    P, _ = K.mode_matrices(model.data, fm)
    PT = np.ascontiguousarray(P.T)
    n_sp = model.n_bodies
    acc: dict[str, Any] = {}
    for h_nom in (H_MAX, 0.5 * H_MAX):
        ns = int(round(T / h_nom))
        h = T / ns
        E = phi_blocks(A, h, h)
        for two in (True, False):
            x, corr = etd2_run(model.data, E, A, x0, u, fm, reg, PT, ns, two)
            acc[f"h_{h_nom * 1e3:g}ms_{'2' if two else '1'}rhs"] = {
                "steps": ns,
                "end_speed_err_rad_s": float(np.abs(x - x_ref)[:n_sp].max()),
                "max_second_order_correction": float(corr),
            }
    # the same with the mode's linear part only (shared by modes; the rest goes into N)
    A_lin = linear_part(model, mode, x0, u)
    ns = int(round(T / H_MAX))
    x, corr = etd2_run(
        model.data, phi_blocks(A_lin, T / ns, T / ns), A_lin, x0, u, fm, reg, PT, ns, False
    )
    acc["h_1ms_1rhs_linear_part"] = {
        "steps": ns,
        "end_speed_err_rad_s": float(np.abs(x - x_ref)[:n_sp].max()),
        "max_second_order_correction": float(corr),
    }
    out["segment"]["etd2_accuracy"] = acc

    # core cost per step against our kernel's cost per step (whole run), interleaved
    ns = int(round(T / H_MAX))
    E = phi_blocks(A, T / ns, T / ns)
    etd2_run(model.data, E, A, x0, u, fm, reg, PT, 2, True)
    core: dict[str, list[float]] = {"2rhs": [], "1rhs": [], "ours": []}
    for _ in range(repeats):
        for two in (True, False):
            t0 = time.perf_counter()
            etd2_run(model.data, E, A, x0, u, fm, reg, PT, ns, two)
            core["2rhs" if two else "1rhs"].append((time.perf_counter() - t0) / ns)
        t0 = time.perf_counter()
        r = simulate(model, x0_run, inputs, t_end=sc.t_end, options=opts)
        core["ours"].append((time.perf_counter() - t0) / r.stats["steps"])
    out["s_per_step"] = {k: statistics.median(v) for k, v in core.items()}
    out["core_1rhs_over_ours_per_step"] = statistics.median(
        [a / b for a, b in zip(core["1rhs"], core["ours"], strict=True)]
    )

    # energy quadrature on the segment
    ref_d = reference_dissipation(sol, model, mode, u, T)
    w_in = float(np.asarray(res.work_in)[-1])
    budget = 1e-6 * max(w_in, float(np.max(res.stored_energy())))
    quad: dict[str, Any] = {}
    for m in (2, 3, 4):
        d = gauss_dissipation(model, mode, u, A, x0, T, m)
        err = float(np.abs(d - ref_d).sum())
        quad[f"gauss_{m}"] = {"abs_err_J": err, "share_of_run_budget": err / budget}
    out["segment"]["dissipation_J_reference"] = float(ref_d.sum())
    out["segment"]["energy_quadrature"] = quad
    out["run_energy_budget_J"] = budget

    # lower bound of a run: 3000 core steps + set-up of every visited mode
    n_min = int(round(sc.t_end / H_MAX))
    tanh_s = median_time(lambda: run_tanh(setup), max(2, repeats // 3))
    best = n_min * out["s_per_step"]["1rhs"] + out["distinct_modes"] * out["setup_s_per_mode"]
    out["lower_bound_run_s"] = best
    shared = (
        n_min * out["s_per_step"]["1rhs"] + out["distinct_linear_parts"] * out["setup_s_per_mode"]
    )
    out["lower_bound_run_shared_s"] = shared
    out["speedup_vs_tanh_upper_bound_shared"] = tanh_s / shared
    fast = (
        n_min * out["s_per_step"]["1rhs"]
        + out["distinct_linear_parts"] * out["setup_fast_s_per_mode"]
    )
    out["lower_bound_run_shared_fast_s"] = fast
    out["speedup_vs_tanh_upper_bound_shared_fast"] = tanh_s / fast
    out["tanh_s"] = tanh_s
    out["speedup_vs_tanh_upper_bound"] = tanh_s / best
    out["ours_s"] = statistics.median(core["ours"]) * out["steps_ours"]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--out", type=Path, default=HERE / "results")
    a = ap.parse_args(argv)
    result: dict[str, Any] = {"h_max_s": H_MAX, "scenarios": {}}
    for name in ("engage-ramp", "tip-in"):
        r = check_scenario(name, a.repeats)
        result["scenarios"][name] = r
        seg = r["segment"]
        print(f"\n=== {name} ===")
        print(
            f"longest one-mode segment {seg['duration_s']:.3f} s (ours {seg['steps_ours']} steps), "
            f"max |lambda| {seg['max_abs_eigenvalue_1_s']:.0f} 1/s"
        )
        for k, v in seg["etd2_accuracy"].items():
            print(
                f"  ETD2 {k:24s} {v['steps']:5d} steps, end speed error "
                f"{v['end_speed_err_rad_s']:.1e} rad/s"
            )
        sp = r["s_per_step"]
        print(
            f"cost per step: ETD2 core {sp['2rhs'] * 1e9:.0f} ns (2 rhs), {sp['1rhs'] * 1e9:.0f} ns "
            f"(1 rhs); ours {sp['ours'] * 1e9:.0f} ns (whole step, {r['steps_ours']} steps a run); "
            f"1-rhs core / ours {r['core_1rhs_over_ours_per_step']:.2f}"
        )
        print(
            f"{r['distinct_modes']} distinct modes a run; matrix functions "
            f"{r['setup_s_per_mode'] * 1e6:.0f} us per mode (scipy expm)"
        )
        for k, v in seg["energy_quadrature"].items():
            print(
                f"  dissipation by {k}: error {v['abs_err_J']:.1e} J = "
                f"{v['share_of_run_budget']:.2g} of the run's residual budget"
            )
        print(
            f"compiled set-up (Taylor + doubling) {r['setup_fast_s_per_mode'] * 1e6:.0f} us per "
            f"mode (max deviation from scipy {r['setup_fast_max_rel_dev_from_scipy']:.1e}); "
            f"one per linear part: lower bound {r['lower_bound_run_shared_fast_s'] * 1e3:.2f} ms, "
            f"speedup at most {r['speedup_vs_tanh_upper_bound_shared_fast']:.0f}x"
        )
        print(
            f"{r['distinct_linear_parts']} distinct linear parts: with one set-up each, the lower "
            f"bound is {r['lower_bound_run_shared_s'] * 1e3:.2f} ms, speedup at most "
            f"{r['speedup_vs_tanh_upper_bound_shared']:.0f}x"
        )
        print(
            f"lower bound of a run {r['lower_bound_run_s'] * 1e3:.2f} ms (ours today "
            f"{r['ours_s'] * 1e3:.1f} ms); tanh baseline {r['tanh_s'] * 1e3:.0f} ms; speedup "
            f"at most {r['speedup_vs_tanh_upper_bound']:.0f}x"
        )
    print()
    write_json(a.out, "exponential_check.json", result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
