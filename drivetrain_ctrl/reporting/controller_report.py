"""Controller report: small-signal analysis of a clutch controller next to its nonlinear run.

:func:`build_report` simulates a scenario with a controller, takes a slip operating point from the
trajectory (``SLIP_DELAY_S`` after the controller start) and a locked one (:func:`locked_trim` at
the lock-up vehicle speed, or the trajectory after lock-up), analyses the clutch loop there
(:mod:`drivetrain_ctrl.linear`, :mod:`drivetrain_ctrl.analysis`), compares the linear closed-loop
prediction of a reference step with the switching plant, and writes into ``out``:

* ``data.json``: every number behind every figure (floats rounded by
  :func:`~drivetrain_ctrl.metrics.json_ready`, keys sorted, no timestamps, paths or wall times:
  byte-identical for the same input);
* ``report.html``: self-contained (figures embedded as base64 PNG);
* ``report.pdf``: the same content drawn with matplotlib only (text pages, then the figures).

``data["modes"][mode][controller]`` (``mode`` in ``slip``, ``lock``) holds the margin keys of
:data:`MARGIN_KEYS`; a figure that is undefined is None with a ``reasons[key]`` entry (in lock
mode the clutch loop is open: every margin is None with that reason; the lock entry gives the
driveline shuffle modes and the torque margin to breakaway instead).

All figures are drawn from ``data`` only (:func:`make_figures`, in
:mod:`drivetrain_ctrl.plotting`), so ``Report.plot()`` needs no re-computation.
"""

from __future__ import annotations

import base64
import dataclasses
import html
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import control
import numpy as np
from numpy.typing import NDArray

from ..control.laws import ControllerSpec, load_controller
from ..core.serialize import json_ready
from ..core.signals import step
from ..linear.clutch import (
    ClutchLoop,
    _controller_sign,
    _judder_threshold,
    clutch_loop,
    judder_threshold,
    locked_analysis,
)
from ..linear.linearisation import linearise_visited_modes, trim_tf
from ..linear.margins import (
    _auto_grid,
    _dt_of,
    db_phase,
    loop_margins,
    nyquist_data,
    poles_of,
    root_locus,
)
from ..linear.operating_point import (
    OperatingPoint,
    _driven_state,
    locked_trim,
    operating_point_from_result,
)
from ..plant.drivetrain import Drivetrain
from ..plant.params import DrivetrainParams, default_params, load_params
from ..scenarios.scenario import Scenario, load_scenario
from ..sim.metrics import engagement_metrics
from ..sim.run import run_scenario
from ..sim.simulator import simulate

__all__ = [
    "Report",
    "build_report",
    "make_figures",
    "MODELS",
    "MARGIN_KEYS",
    "SECTIONS",
    "SLIP_DELAY_S",
    "DISAGREEMENT_THRESHOLD",
]

F64 = NDArray[np.float64]

#: model kinds a report can be built on
MODELS: tuple[str, ...] = ("reduced", "full")

#: modes held for less than this [s] by the engagement run are left out of ``visited_modes``
VISITED_MIN_S: float = 0.01

#: keys present for every mode and controller in ``data["modes"]``
MARGIN_KEYS: tuple[str, ...] = (
    "gain_margin_db",
    "phase_margin_deg",
    "delay_margin_s",
    "disk_margin_db",
    "disk_margin_deg",
    "ms",
    "mt",
    "crossover_rad_s",
    "closed_loop_poles",
    "natural_frequencies_hz",
)

#: section titles of the HTML and PDF reports, in order
SECTIONS: tuple[str, ...] = (
    "Model and operating points",
    "Transfer functions",
    "Bode diagrams of L, S, T",
    "Root loci",
    "Nyquist diagram",
    "Stability margins per mode",
    "Linear prediction vs switching plant",
    "Engagement metrics",
    "Where linear and nonlinear disagree",
)

#: the slip operating point is taken this long after the controller start [s]
SLIP_DELAY_S: float = 0.3
#: horizon of the step comparison [s]
STEP_HORIZON_S: float = 1.0
#: reference steps of the comparison [rpm]: a small one (linear range) and a large one
STEP_SIZES_RPM: dict[str, float] = {"small": 20.0, "large": -500.0}
#: the linear prediction "disagrees" when peak ``|nonlinear - linear|`` exceeds this fraction of the
#: peak linear response
DISAGREEMENT_THRESHOLD: float = 0.1
#: samples of the comparison / engagement series and of the frequency grids
N_STEP_SAMPLES: int = 201
ENGAGEMENT_RATE_HZ: float = 100.0
N_FREQ: int = 300

_RPM = 30.0 / math.pi  # rad/s -> rpm


# ---------------------------------------------------------------------------------------------
# result
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Report:
    """A built report: output directory ``out``, the JSON data ``data`` (as written to
    ``data.json``) and the files written (``data.json``, ``report.html``, ``report.pdf``)."""

    out: Path
    data: dict[str, Any]
    files: tuple[Path, ...]

    def plot(self) -> dict[str, Any]:
        """The report's figures (``{name: matplotlib Figure}``), drawn from ``data``."""
        return make_figures(self.data)


# ---------------------------------------------------------------------------------------------
# argument handling
# ---------------------------------------------------------------------------------------------


def _resolve_params(params: Any) -> tuple[DrivetrainParams, str]:
    if params is None:
        p = default_params()
        return p, p.name
    if isinstance(params, DrivetrainParams):
        return params, params.name
    if isinstance(params, str | Path):
        try:
            p = load_params(params)
        except (ValueError, FileNotFoundError) as exc:
            raise ValueError(f"params = {str(params)!r}: {exc}") from exc
        return p, p.name
    raise TypeError(
        f"params: None, a parameter-set name, a TOML path or DrivetrainParams, got "
        f"{type(params).__name__}"
    )


def _check_model(model: Any) -> str:
    if model not in MODELS:
        raise ValueError(f"model = {model!r}: must be one of {list(MODELS)}")
    return str(model)


# ---------------------------------------------------------------------------------------------
# numbers
# ---------------------------------------------------------------------------------------------


def _tf_dict(sys: Any) -> dict[str, Any]:
    """Coefficients (descending powers) of the SISO ``sys`` from
    :func:`~drivetrain_ctrl.linear.trim_tf` (leading numerator round-off dropped where the Markov
    parameter behind it is zero). No clipping relative to the largest coefficient: a model's
    polynomials span many decades (the full model's plant: 1 to 1e30)."""
    t = trim_tf(sys)
    return {
        "num": [float(v) for v in np.atleast_1d(np.asarray(t.num[0][0], dtype=float))],
        "den": [float(v) for v in np.atleast_1d(np.asarray(t.den[0][0], dtype=float))],
        "dt": _dt_of(t),
    }


def _tf_text(d: dict[str, Any]) -> str:
    var = "z" if d["dt"] else "s"

    def poly(c: list[float]) -> str:
        n = len(c) - 1
        terms = []
        for k, v in enumerate(c):
            if v == 0:
                continue
            p = n - k
            mon = "" if p == 0 else (var if p == 1 else f"{var}^{p}")
            terms.append(f"{v:.4g}" + (f" {mon}" if mon else ""))
        return " + ".join(terms).replace("+ -", "- ") or "0"

    s = f"({poly(d['num'])}) / ({poly(d['den'])})"
    return s + (f"   [dt = {d['dt']:g} s]" if d["dt"] else "")


def _omega_grid(L: Any) -> F64:
    """Log frequency grid [rad/s] around the poles and zeros of ``L`` (to Nyquist if discrete):
    :data:`N_FREQ` points over two decades beyond them."""
    return _auto_grid(L, n=N_FREQ, span=100.0, tiny=1e-9)


def _bode(sys: Any, w: F64) -> dict[str, list[float]]:
    db, ph = db_phase(control.frequency_response(sys, w).complex)
    return {
        "omega": list(map(float, w)),
        "magnitude_db": list(map(float, db)),
        "phase_deg": list(map(float, ph)),
    }


def _margins_entry(cl: ClutchLoop) -> dict[str, Any]:
    m = loop_margins(cl.L).to_dict()
    reasons = dict(m.pop("reasons") or {})
    out = dict(m)
    for k in MARGIN_KEYS:
        v = out.get(k)
        if v is None or (isinstance(v, list) and not v and k == "closed_loop_poles"):
            out[k] = None
            reasons.setdefault(
                k, reasons.get(k.replace("_db", "").replace("_deg", ""), "undefined")
            )
    if out.get("natural_frequencies_hz") == []:
        out["natural_frequencies_hz"] = None
        reasons["natural_frequencies_hz"] = "no oscillatory closed-loop pole"
    out["reasons"] = reasons
    return out


def _slip_root_loci(op: OperatingPoint, ctrl: Any, cl: ClutchLoop) -> dict[str, Any]:
    """Root loci over the controller gain (k_r for law 6) and over the clutch friction slope."""
    out: dict[str, Any] = {}
    static = ctrl.lti.nstates == 0 and not ctrl.is_discrete
    factors = np.geomspace(0.1, 10.0, 21)
    if static:
        k0 = float(np.asarray(ctrl.lti.D).reshape(-1)[0])
        rl = root_locus(op, ctrl, parameter="k_r", values=list(k0 * factors))
        d = rl.to_dict()
        d["nominal"] = k0
        out["gain"] = d
    else:
        # a dynamic or sampled controller: its whole gain scaled by a factor g, 1 + g L = 0
        pts = []
        for g in factors:
            cl_g = control.feedback(control.ss(cl.L) * float(g), 1)
            ps = poles_of(np.linalg.eigvals(cl_g.A) if cl_g.nstates else [], cl.dt)
            mr = max((p.real for p in ps), default=-math.inf)
            pts.append(
                {
                    "value": float(g),
                    "poles": [[p.real, p.imag] for p in ps],
                    "max_real": mr,
                    "stable": bool(mr < 0),
                }
            )
        out["gain"] = {"parameter": "gain_factor", "unit": "-", "nominal": 1.0, "points": pts}
    # physical parameter: the clutch friction slope mu' (judder), through the critical value
    try:
        if ctrl.is_discrete:
            crit = judder_threshold(op, None).mu_slope_crit
        else:
            crit = _judder_threshold(cl.op, cl.engine, cl.L).mu_slope_crit
    except (ValueError, RuntimeError):
        crit = -0.01
    if not (math.isfinite(crit) and crit != 0):
        crit = -0.01
    vals = [float(v) for v in np.linspace(0.0, 1.5 * crit, 16)]
    if not ctrl.is_discrete:
        d = root_locus(op, ctrl, parameter="mu_slope", values=vals).to_dict()
    else:
        pts = []
        for v in vals:
            c2 = clutch_loop(op, ctrl, mu_slope=v)
            ps = poles_of(np.linalg.eigvals(c2.closed_loop.A), c2.dt)
            mr = max((p.real for p in ps), default=-math.inf)
            pts.append(
                {
                    "value": v,
                    "poles": [[p.real, p.imag] for p in ps],
                    "max_real": mr,
                    "stable": bool(mr < 0),
                }
            )
        d = {"parameter": "mu_slope", "unit": "s/rad", "points": pts}
    d["judder_mu_slope_crit"] = crit
    d["nominal"] = cl.engine.mu_slope_torque / max(cl.engine.k13, 1e-12)
    out["mu_slope"] = d
    return out


# ---------------------------------------------------------------------------------------------
# operating points
# ---------------------------------------------------------------------------------------------


def _slip_point(res: Any, dtr: Drivetrain, start: float) -> OperatingPoint:
    t_end = float(res.t[-1])
    t = min(start + SLIP_DELAY_S, t_end)
    op = operating_point_from_result(res, t, drivetrain=dtr)
    if op.clutch_mode in ("slip+", "slip-"):
        return op
    # the first instant after the start at which the clutch slips
    for k in np.flatnonzero(np.asarray(res.t) > start):
        op = operating_point_from_result(res, float(res.t[k]), drivetrain=dtr)
        if op.clutch_mode in ("slip+", "slip-"):
            return op
    raise ValueError("scenario: the clutch never slips after the controller start; no slip point")


def _lock_point(
    res: Any, dtr: Drivetrain, lock_t: float | None
) -> tuple[OperatingPoint | None, str]:
    T = np.asarray(res.t)
    if lock_t is None:
        return None, "no lock-up in the simulated scenario"
    v = float(np.interp(lock_t, T, res.state("v_vehicle")))
    try:
        op = locked_trim(dtr, vehicle_speed_kmh=v * 3.6)
        return op, f"locked_trim at the lock-up vehicle speed {v * 3.6:.4g} km/h"
    except (ValueError, RuntimeError) as exc:
        t = min(lock_t + 0.5, float(T[-1]))
        op = operating_point_from_result(res, t, drivetrain=dtr)
        if op.clutch_mode != "stuck":
            return None, f"locked_trim failed ({exc}) and the clutch is not stuck at t = {t:.4g} s"
        return op, f"trajectory at t = {t:.4g} s (locked_trim failed: {exc})"


# ---------------------------------------------------------------------------------------------
# linear vs nonlinear
# ---------------------------------------------------------------------------------------------


def _matched_controller(ctrl: Any, op: OperatingPoint) -> Any:
    """``ctrl`` acting from the start of a run at ``op`` (no start time), with its LTI state set so
    that its output equals the pedal there (with its own reference)."""
    c = dataclasses.replace(ctrl, start_time=None)
    ref = c.reference
    n = c.lti.nstates
    if n == 0:
        return c
    sgn = _controller_sign(c, op)
    e = 0.0
    for coef, src in c.measurement:
        e += coef * (float(ref(op.t or 0.0)) if src == "ref" else op.state(src))
    v = (op.input("pedal") - c.offset) / sgn
    C = np.asarray(c.lti.C, dtype=float)
    D = float(np.asarray(c.lti.D).reshape(-1)[0])
    x = np.linalg.pinv(C) @ np.array([v - D * e])
    return dataclasses.replace(c, initial_lti_state=tuple(float(q) for q in x))


@dataclass(frozen=True)
class _StepRuns:
    """What the step comparisons share: the controller matched at the slip point and the
    nonlinear run with the nominal reference (the same for every step size)."""

    horizon: float
    controller: Any
    nominal: Any


def _step_run(sc: Scenario, dtr: Drivetrain, op: OperatingPoint, c: Any, H: float) -> Any:
    t0 = float(op.t or 0.0)
    return simulate(
        dtr.model,
        np.array(op.x),
        sc.input_signals(),
        t0=t0,
        t_end=t0 + H,
        controller=c,
        controller_initial=op.input("pedal"),
    )


def _nominal_step_run(sc: Scenario, dtr: Drivetrain, ctrl: Any, op: OperatingPoint) -> _StepRuns:
    H = min(STEP_HORIZON_S, sc.t_end - float(op.t or 0.0))
    if not H > 0.0:
        raise ValueError(
            f"scenario {sc.name!r}: t_end = {sc.t_end!r} s leaves no time after the slip point at "
            f"{float(op.t or 0.0):g} s (controller start + {SLIP_DELAY_S:g} s) for the step "
            "responses: make t_end longer"
        )
    # the controller state is matched to the pedal with the nominal reference in every run (the
    # step must reach the controller, not be absorbed into its initial state)
    c0 = _matched_controller(ctrl, op)
    return _StepRuns(H, c0, _step_run(sc, dtr, op, c0, H))


def _step_comparison(
    sc: Scenario,
    dtr: Drivetrain,
    params: Any,
    op: OperatingPoint,
    cl: ClutchLoop,
    d_rpm: float,
    shared: _StepRuns,
) -> dict[str, Any]:
    t0, H = float(op.t or 0.0), shared.horizon
    d = d_rpm / _RPM
    c = dataclasses.replace(shared.controller, reference=shared.controller.reference + step(t0, d))
    runs = {"nominal": shared.nominal, "perturbed": _step_run(sc, dtr, op, c, H)}
    tg = np.linspace(0.0, H, N_STEP_SAMPLES)

    def at(res: Any, name: str) -> F64:
        return np.interp(t0 + tg, np.asarray(res.t), res.state(name))

    dnl = at(runs["perturbed"], "omega_engine") - at(runs["nominal"], "omega_engine")
    sys = cl.closed_loop
    if cl.dt:
        tk = np.arange(0.0, H + cl.dt / 2, cl.dt)
        y = control.forced_response(sys, T=tk, U=np.full(tk.size, d)).outputs
        lin = np.interp(tg, tk, np.asarray(y).reshape(-1))
    else:
        y = control.forced_response(sys, T=tg, U=np.full(tg.size, d)).outputs
        lin = np.asarray(y).reshape(-1)
    diff = dnl - lin
    peak_lin = float(np.max(np.abs(lin)))
    peak_diff = float(np.max(np.abs(diff)))
    rel = peak_diff / peak_lin if peak_lin > 0 else math.inf
    k_exceed = np.flatnonzero(np.abs(diff) > DISAGREEMENT_THRESHOLD * peak_lin)
    # what the nonlinear runs did that the linear model cannot
    causes: list[str] = []
    pert = runs["perturbed"]
    clutch_modes = pert.mode_series("clutch")
    mode0 = op.clutch_mode
    if "stuck" in clutch_modes:
        i = clutch_modes.index("stuck")
        causes.append(f"lock-up: the clutch sticks at t = {float(pert.t[i]):.4g} s")
    other = "slip-" if mode0 == "slip+" else "slip+"
    if other in clutch_modes:
        causes.append("sign switch: the slip changes sign (law (6) switches branch)")
    act = params.actuator
    ip = dtr.model.input_names.index("pedal")
    pedal = np.asarray(pert.u)[:, ip]
    if np.any(pedal <= act.x_min + 1e-9) or np.any(pedal >= act.x_max - 1e-9):
        causes.append(
            f"saturation: the actuator reaches its stroke limit [{act.x_min}, {act.x_max}] m"
        )
    es = cl.engine
    if es.mu_slope_torque != 0.0:
        causes.append(
            f"slip-dependent mu: friction slope c = {es.mu_slope_torque:.4g} N m s/rad at the "
            "operating point, changing with the slip"
        )
    nom = runs["nominal"]
    iw = dtr.model.state_index("omega_engine")
    driven = _driven_state(dtr)
    slip0 = op.state("omega_engine") - op.state(driven)
    slip1 = float(np.asarray(nom.x)[-1, iw]) - float(nom.state(driven)[-1])
    drift = abs(slip1 - slip0) / max(abs(slip0), 1e-9)
    if drift > 0.25:
        causes.append(
            f"operating-point drift: slip is not an equilibrium; the nominal slip speed moves "
            f"from {slip0:.4g} to {slip1:.4g} rad/s over the horizon ({100 * drift:.0f} %)"
        )
    agree = bool(rel <= DISAGREEMENT_THRESHOLD)
    if agree:
        stmt = (
            f"Reference step {d_rpm:+g} rpm: the linear prediction and the switching plant agree "
            f"(peak difference {peak_diff * _RPM:.3g} rpm = {100 * rel:.2g} % of the linear peak "
            f"response, threshold {100 * DISAGREEMENT_THRESHOLD:g} %)."
        )
    else:
        when = float(tg[k_exceed[0]]) if k_exceed.size else 0.0
        why = "; ".join(causes) if causes else "no mode change detected (nonlinear gains)"
        stmt = (
            f"Reference step {d_rpm:+g} rpm: the linear prediction and the switching plant "
            f"disagree from {when:.3g} s after the step (peak difference {peak_diff * _RPM:.3g} "
            f"rpm = {100 * rel:.3g} % of the linear peak response, RMS "
            f"{float(np.sqrt(np.mean(diff**2))) * _RPM:.3g} rpm). Cause(s): {why}."
        )
    return {
        "step_rpm": d_rpm,
        "t_start_s": t0,
        "t_s": list(map(float, tg)),
        "linear_rpm": list(map(float, lin * _RPM)),
        "nonlinear_rpm": list(map(float, dnl * _RPM)),
        "rms_difference_rpm": float(np.sqrt(np.mean(diff**2))) * _RPM,
        "peak_difference_rpm": peak_diff * _RPM,
        "peak_linear_rpm": peak_lin * _RPM,
        "relative_peak_difference": rel,
        "threshold": DISAGREEMENT_THRESHOLD,
        "first_exceedance_s": float(tg[k_exceed[0]]) if k_exceed.size else None,
        "agree": agree,
        "causes": causes,
        "statement": stmt,
        "clutch_modes_nonlinear": sorted(set(clutch_modes)),
    }


def _engagement_series(res: Any, sc: Scenario, dtr: Drivetrain) -> dict[str, Any]:
    T = np.asarray(res.t)
    t = np.arange(0.0, float(T[-1]) + 1e-12, 1.0 / ENGAGEMENT_RATE_HZ)
    driven = _driven_state(dtr)
    ip = dtr.model.input_names.index("pedal")
    ref = sc.reference
    return {
        "t_s": list(map(float, t)),
        "omega_engine_rpm": list(map(float, np.interp(t, T, res.state("omega_engine")) * _RPM)),
        "omega_driven_rpm": list(map(float, np.interp(t, T, res.state(driven)) * _RPM)),
        "omega_ref_rpm": [float(ref(float(x))) * _RPM for x in t] if ref is not None else None,
        "x_c_m": list(map(float, np.interp(t, T, np.asarray(res.u)[:, ip]))),
        "v_vehicle_kmh": list(map(float, np.interp(t, T, res.state("v_vehicle")) * 3.6)),
        "driven_state": driven,
    }


# ---------------------------------------------------------------------------------------------
# builder
# ---------------------------------------------------------------------------------------------


def build_report(
    *,
    controller: str | Path | ControllerSpec = "paper",
    params: str | Path | DrivetrainParams | None = None,
    model: str = "reduced",
    scenario: str | Path | Scenario = "paper-start",
    out: str | Path,
) -> Report:
    """Build the report of ``controller`` (built-in name, TOML file or spec) on ``model``
    (``"reduced"`` / ``"full"``) with parameter set ``params`` (None: default; a name or TOML path:
    :func:`~drivetrain_ctrl.params.load_params`) in ``scenario`` (a closed-loop scenario: name,
    TOML file or :class:`~drivetrain_ctrl.scenarios.Scenario`); writes ``data.json``, ``report.html`` and ``report.pdf`` into ``out`` (created).

    Raises ValueError (ControllerError / ScenarioError) naming the argument for a bad controller,
    model, parameter set or scenario.
    """
    kind = _check_model(model)
    spec = load_controller(controller)
    p, pname = _resolve_params(params)
    sc = load_scenario(scenario, params=p)
    if not sc.needs_controller:
        raise ValueError(
            f"scenario = {sc.name!r}: open loop (it gives the pedal signal); the report needs a "
            "closed-loop scenario with an engine-speed reference (e.g. 'paper-start')"
        )
    outp = Path(out)
    outp.mkdir(parents=True, exist_ok=True)
    dtr = sc.drivetrain(p, kind=kind)
    # built once (as sc.run would build it, warnings included) and simulated as is
    ctrl = sc.make_controller(dtr, spec)
    res = run_scenario(sc, dtr, controller=ctrl)
    metrics = engagement_metrics(res, dtr, start=sc.start_time, reference=sc.reference)
    cname = spec.name

    # slip mode
    op_s = _slip_point(res, dtr, sc.start_time)
    cl = clutch_loop(op_s, ctrl)
    slip_entry = _margins_entry(cl)
    w = _omega_grid(cl.L)
    tfs = {
        "L": _tf_dict(cl.L),
        "S": _tf_dict(cl.S),
        "T": _tf_dict(cl.T),
        "plant": _tf_dict(cl.plant),
        "controller": _tf_dict(cl.controller),
        "actuator": _tf_dict(cl.actuator),
        "x_c_to_tau13": _tf_dict(cl.x_c_to_tau13),
        "tau13_to_omega1": _tf_dict(cl.tau13_to_omega1),
        "theta_to_omega1": _tf_dict(cl.theta_to_omega1),
        "x_c_to_accel": _tf_dict(cl.x_c_to_accel),
    }
    slip_entry["transfer_functions"] = tfs
    slip_entry["bode"] = {
        "L": _bode(cl.L, w),
        "S": _bode(cl.S, w),
        "T": _bode(cl.T, w),
        "PS": _bode(cl.PS, w),
    }
    slip_entry["nyquist"] = nyquist_data(cl.L, omega=[float(v) for v in w]).to_dict()
    slip_entry["root_locus"] = _slip_root_loci(op_s, ctrl, cl)
    slip_entry["engine_side"] = dataclasses.asdict(cl.engine)
    slip_entry["discrete"] = cl.discrete
    slip_entry["sample_period_s"] = cl.dt

    # lock mode
    op_l, lock_how = _lock_point(res, dtr, metrics.get("lockup_time_s"))
    reason_open = (
        "clutch locked: x_c does not change the transmitted torque while the clutch is stuck, so "
        "the clutch loop is open (margins undefined; see shuffle_modes and breakaway_margins)"
    )
    lock_entry: dict[str, Any] = dict.fromkeys(MARGIN_KEYS)
    lock_entry["reasons"] = dict.fromkeys(MARGIN_KEYS, reason_open)
    lock_entry["operating_point_source"] = lock_how
    if op_l is not None:
        la = locked_analysis(op_l).to_dict()
        lock_entry["shuffle_modes"] = la["shuffle_modes"]
        lock_entry["open_loop_poles"] = la["poles"]
        lock_entry["breakaway_margins"] = la["breakaway_margins"]
        lock_entry["margins_reason"] = la["margins_reason"]
    else:
        lock_entry["shuffle_modes"] = None
        lock_entry["open_loop_poles"] = None
        lock_entry["breakaway_margins"] = None
        lock_entry["reasons"]["shuffle_modes"] = lock_how

    shared = _nominal_step_run(sc, dtr, ctrl, op_s)
    comparison = {
        name: _step_comparison(sc, dtr, p, op_s, cl, d, shared)
        for name, d in STEP_SIZES_RPM.items()
    }
    statements = [c["statement"] for c in comparison.values()]

    data: dict[str, Any] = {
        "format": "drivetrain_ctrl report 1",
        "inputs": {
            "controller": spec.to_dict(),
            "controller_name": cname,
            "params": pname,
            "model": kind,
            "scenario": sc.name,
            "scenario_description": sc.description,
            "slip_delay_s": SLIP_DELAY_S,
        },
        "operating_points": {
            "slip": op_s.to_dict(),
            "lock": op_l.to_dict() if op_l is not None else None,
        },
        "modes": {"slip": {cname: slip_entry}, "lock": {cname: lock_entry}},
        "engagement_metrics": metrics,
        "engagement_series": _engagement_series(res, sc, dtr),
        "linear_vs_nonlinear": {"steps": comparison, "statements": statements},
        "visited_modes": [
            {
                "label": v.label,
                "duration_s": v.duration_s,
                "t_s": v.op.t,
                "n_states": v.sys.nstates,
                "natural_frequencies_hz": list(v.natural_frequencies_hz),
                "damping": list(v.damping),
            }
            for v in linearise_visited_modes(res, drivetrain=dtr, min_duration=VISITED_MIN_S)
        ],
    }
    data = json_ready(data)
    text = json.dumps(data, sort_keys=True, indent=1, allow_nan=False) + "\n"
    files = []
    fj = outp / "data.json"
    fj.write_text(text, encoding="utf-8")
    files.append(fj)
    figs = make_figures(data)
    fh = outp / "report.html"
    fh.write_text(_html(data, figs), encoding="utf-8")
    files.append(fh)
    fp = outp / "report.pdf"
    _pdf(data, figs, fp)
    files.append(fp)
    return Report(out=outp, data=data, files=tuple(files))


# ---------------------------------------------------------------------------------------------
# figures (from data only)
# ---------------------------------------------------------------------------------------------


def make_figures(data: dict[str, Any]) -> dict[str, Any]:
    """``{name: Figure}``: bode, root_locus, nyquist, step, engagement, lock (from ``data``;
    :func:`drivetrain_ctrl.plotting.report_figures`)."""
    from .figures import report_figures

    return dict(report_figures(data))


# ---------------------------------------------------------------------------------------------
# text content shared by HTML and PDF
# ---------------------------------------------------------------------------------------------


def _fmt(v: Any) -> str:
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _sections(
    data: dict[str, Any],
) -> list[tuple[str, list[str], list[tuple[str, list[list[str]]]], list[str]]]:
    """``(title, paragraphs, tables, figure names)`` per section; a table is ``(caption, rows)``
    with the first row the header."""
    inp = data["inputs"]
    cname = inp["controller_name"]
    slip = data["modes"]["slip"][cname]
    lock = data["modes"]["lock"][cname]
    ops = data["operating_points"]
    out: list[tuple[str, list[str], list[tuple[str, list[list[str]]]], list[str]]] = []

    # 1 model and operating points
    paras = [
        f"Model: {inp['model']}; parameter set: {inp['params']}; scenario: {inp['scenario']} "
        f"({inp['scenario_description']}); controller: {cname} "
        f"({', '.join(f'{k} = {_fmt(v)}' for k, v in sorted(inp['controller'].items()) if v is not None)}).",
        f"Slip operating point: the simulated trajectory at t = {_fmt(ops['slip']['t_s'])} s "
        f"({_fmt(inp['slip_delay_s'])} s after the controller start).",
        f"Lock operating point: {lock['operating_point_source']}.",
    ]
    rows = [["", "slip", "lock"]]
    names = sorted(
        set(ops["slip"]["state"]) | set(ops["slip"]["inputs"]) | set(ops["slip"]["modes"])
    )
    lk = ops["lock"] or {"state": {}, "inputs": {}, "modes": {}}
    for n in names:

        def g(o: dict[str, Any], n: str = n) -> str:
            for grp in ("state", "inputs", "modes"):
                if n in o[grp]:
                    return _fmt(o[grp][n])
            return "n/a"

        rows.append([n, g(ops["slip"]), g(lk)])
    cert = ops["slip"]["certificate"]
    paras.append(
        f"Slip certificate: slip speed {_fmt(cert['slip_speed_rad_s'])} rad/s, slip acceleration "
        f"{_fmt(cert['slip_accel_rad_s2'])} rad/s^2, time to lock {_fmt(cert['time_to_lock_s'])} s "
        "(a slip point is not an equilibrium)."
    )
    out.append((SECTIONS[0], paras, [("Operating points (SI units)", rows)], ["engagement"]))

    # 2 transfer functions
    rows = [["transfer function", "num / den"]]
    for k, d in sorted(slip["transfer_functions"].items()):
        rows.append([k, _tf_text(d)])
    out.append(
        (
            SECTIONS[1],
            [
                "Linearised clutch loop at the slip point (negative feedback, L = C P, "
                "S = 1/(1+L), T = L/(1+L)); the plant P includes the sign block, the actuator and "
                "the engine side."
            ],
            [("Transfer functions (coefficients in descending powers)", rows)],
            [],
        )
    )
    # 3 bode
    out.append(
        (
            SECTIONS[2],
            [
                "Frequency responses of the loop, sensitivity and complementary sensitivity at the slip point."
            ],
            [],
            ["bode"],
        )
    )
    # 4 root loci
    rl = slip["root_locus"]
    rg = rl["gain"]
    paras = [
        f"Left: closed-loop poles over the controller gain {rg['parameter']} [{rg['unit']}] "
        f"(nominal {_fmt(rg.get('nominal'))}), crossing {_fmt(rg.get('crossing'))}. Right: over the "
        f"clutch friction slope mu' [s/rad] (nominal {_fmt(rl['mu_slope'].get('nominal'))}); "
        f"judder threshold {_fmt(rl['mu_slope'].get('judder_mu_slope_crit'))} s/rad, crossing on "
        f"the grid {_fmt(rl['mu_slope'].get('crossing'))}."
    ]
    out.append((SECTIONS[3], paras, [], ["root_locus"]))
    # 5 nyquist
    ny = slip["nyquist"]
    out.append(
        (
            SECTIONS[4],
            [
                f"Encirclements of -1: {ny['encirclements']}; open-loop unstable poles: "
                f"{ny['open_loop_unstable_poles']}; closed-loop unstable poles Z = N + P = "
                f"{ny['closed_loop_unstable_poles']}."
            ],
            [],
            ["nyquist"],
        )
    )
    # 6 margins
    rows = [["figure", "slip", "lock"]]
    for k in MARGIN_KEYS:

        def cell(e: dict[str, Any], k: str = k) -> str:
            v = e.get(k)
            if v is None:
                return (
                    "n/a (" + str(e.get("reasons", {}).get(k, "undefined")) + ")"
                    if e is slip
                    else "n/a"
                )
            if k == "closed_loop_poles":
                return "; ".join(f"{p['real']:.4g}{p['imag']:+.4g}j" for p in v)
            if isinstance(v, list):
                return ", ".join(_fmt(x) for x in v)
            return _fmt(v)

        rows.append([k, cell(slip), cell(lock)])
    paras = [f"Lock mode: {lock['reasons'][MARGIN_KEYS[0]]}."]
    for m in lock.get("shuffle_modes") or []:
        paras.append(
            f"Locked driveline shuffle mode: {m['natural_frequency_hz']:.4g} Hz natural, "
            f"{m['damped_frequency_hz']:.4g} Hz damped, damping ratio {m['damping']:.4g}."
        )
    for el, b in sorted((lock.get("breakaway_margins") or {}).items()):
        paras.append(
            f"Torque margin to breakaway of the {el}: {_fmt(b['margin'])} N m (static capacity "
            f"{_fmt(b['capacity'])} N m, carried {_fmt(b['torque'])} N m)."
        )
    vrows = [["mode (friction modes, regions, table segments)", "time held [s]", "natural "
              "frequencies [Hz] (damping)"]]  # fmt: skip
    for v in data.get("visited_modes", []):
        fr = ", ".join(
            f"{f:.4g} ({z:.3g})"
            for f, z in zip(v["natural_frequencies_hz"], v["damping"], strict=True)
        )
        vrows.append([v["label"], _fmt(v["duration_s"]), fr or "none (no oscillatory pole)"])
    paras.append(
        "Every mode the engagement run holds for at least "
        f"{VISITED_MIN_S * 1e3:g} ms, linearised at the middle of its longest interval:"
    )
    out.append(
        (
            SECTIONS[5],
            paras,
            [(f"Margins, controller {cname}", rows), ("Natural frequencies in every mode", vrows)],
            ["lock"],
        )
    )
    # 7 step comparison
    rows = [
        [
            "step",
            "size [rpm]",
            "peak linear [rpm]",
            "peak diff [rpm]",
            "RMS diff [rpm]",
            "rel. peak diff",
            "agree",
        ]
    ]
    for name, s in sorted(data["linear_vs_nonlinear"]["steps"].items()):
        rows.append(
            [
                name,
                _fmt(s["step_rpm"]),
                _fmt(s["peak_linear_rpm"]),
                _fmt(s["peak_difference_rpm"]),
                _fmt(s["rms_difference_rpm"]),
                _fmt(s["relative_peak_difference"]),
                _fmt(s["agree"]),
            ]
        )
    out.append(
        (
            SECTIONS[6],
            [
                "A step of the engine-speed reference at the slip operating point: the linear "
                "closed loop (control.forced_response) against the difference of two nonlinear "
                "simulations (stepped minus nominal reference) started from the same state."
            ],
            [("Step comparison (engine speed)", rows)],
            ["step"],
        )
    )
    # 8 engagement metrics
    rows = [["metric", "value"]] + [
        [k, _fmt(v) if not isinstance(v, list) else "; ".join(map(str, v))]
        for k, v in sorted(data["engagement_metrics"].items())
    ]
    out.append((SECTIONS[7], [], [("Engagement metrics", rows)], []))
    # 9 statement
    out.append((SECTIONS[8], list(data["linear_vs_nonlinear"]["statements"]), [], []))
    return out


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _html(data: dict[str, Any], figs: dict[str, Any]) -> str:
    inp = data["inputs"]
    e = html.escape
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>Clutch controller report: {e(inp['controller_name'])}</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
        "table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #999;"
        "padding:2px 6px;font-size:0.9em;text-align:left}img{max-width:100%}</style>",
        "</head><body>",
        f"<h1>Clutch controller report: {e(inp['controller_name'])} on the {e(inp['model'])} "
        f"model, scenario {e(inp['scenario'])}</h1>",
    ]
    for title, paras, tables, fnames in _sections(data):
        parts.append(f"<h2>{e(title)}</h2>")
        parts += [f"<p>{e(p)}</p>" for p in paras]
        for cap, rows in tables:
            parts.append(f"<table><caption>{e(cap)}</caption>")
            parts.append("<tr>" + "".join(f"<th>{e(c)}</th>" for c in rows[0]) + "</tr>")
            for r in rows[1:]:
                parts.append("<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>")
            parts.append("</table>")
        for f in fnames:
            parts.append(f'<img alt="{e(f)}" src="data:image/png;base64,{_png(figs[f])}">')
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def _pdf(data: dict[str, Any], figs: dict[str, Any], path: Path) -> None:
    import textwrap

    from .figures import write_text_pdf

    lines: list[tuple[str, str]] = []  # (style, text)
    inp = data["inputs"]
    lines.append(
        ("h1", f"Clutch controller report: {inp['controller_name']} ({inp['model']} model)")
    )
    order: list[str] = []
    for title, paras, tables, fnames in _sections(data):
        lines.append(("h2", title))
        for p in paras:
            lines += [("p", s) for s in textwrap.wrap(p, 105)]
        for cap, rows in tables:
            lines.append(("p", cap + ":"))
            width = [min(max(len(r[i]) for r in rows), 60) for i in range(len(rows[0]))]
            for r in rows:
                txt = "  ".join(c[:60].ljust(w) for c, w in zip(r, width, strict=True))
                lines += [("t", s) for s in textwrap.wrap(txt, 120, drop_whitespace=False)]
        lines.append(("p", ""))
        order += [f for f in fnames if f not in order]
    write_text_pdf(lines, [figs[f] for f in order + [f for f in figs if f not in order]], path)
