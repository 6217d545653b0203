"""The numbers of a controller report: one closed-loop run of a scenario, the clutch loop at a slip
operating point and the driveline at a locked one, and the linear prediction of reference steps
against the switching plant.

:func:`analyse_controller` returns the report's data (every number behind every figure, JSON-ready:
byte-identical for the same input); :mod:`drivetrain_ctrl.reporting.controller_report` renders it.
Nothing here draws: a second report can render several analyses.

``data["modes"][mode][controller]`` (``mode`` in ``slip``, ``lock``) holds the margin keys of
:data:`MARGIN_KEYS`; a figure that is undefined is None with a ``reasons[key]`` entry (in lock
mode the clutch loop is open: every margin is None with that reason; the lock entry gives the
driveline shuffle modes and the torque margin to breakaway instead). The slip operating point is
taken ``SLIP_DELAY_S`` after the controller start; the locked one by :func:`locked_trim` at the
lock-up vehicle speed, or from the trajectory after lock-up. ``data["modes"]["slip"][controller]
["judder"]`` holds the judder threshold: ``numeric`` (:func:`~drivetrain_ctrl.linear.clutch.judder_crossing`,
on any model; its ``mu_slope_crit`` None with ``reason`` when there is none) and ``closed_form``
(:func:`~drivetrain_ctrl.linear.clutch.judder_threshold`; None with ``closed_form_reason`` off the
reduced model or for a sampled controller). No default value ever stands in for a figure that
cannot be computed.
"""

from __future__ import annotations

import dataclasses
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
from ..core.units import M_S_TO_KMH, RAD_S_TO_RPM
from ..linear.clutch import (
    ClutchLoop,
    _controller_sign,
    _judder_threshold,
    _sampled_loop_poles,
    clutch_loop,
    judder_crossing,
    locked_analysis,
)
from ..linear.linearisation import linearise, linearise_visited_modes, trim_tf
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
    SLIP_DELAY_S,
    OperatingPoint,
    _driven_state,
    locked_trim,
    operating_point_from_result,
    slip_point_after_start,
)
from ..plant.drivetrain import Drivetrain
from ..plant.params import DrivetrainParams, default_params, load_params
from ..scenarios.scenario import Scenario, load_scenario
from ..sim.simulator import simulate
from ..studies.case import Case, simulate_case

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


#: points of the root locus over the friction slope mu', from 0 to 1.5 times the judder threshold
N_MU_SLOPE: int = 21


#: span [s/rad] of that locus when there is no threshold to centre it on (a plot range, never
#: reported as a threshold)
MU_SLOPE_SPAN_S_RAD: float = 0.01


_RPM = RAD_S_TO_RPM  # rad/s -> rpm


def _resolve_params(params: object) -> tuple[DrivetrainParams, str]:
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


def _tf_dict(sys: Any) -> dict[str, Any]:
    """Coefficients (descending powers) of the SISO ``sys`` from
    :func:`~drivetrain_ctrl.linear.linearisation.trim_tf` (leading numerator round-off dropped where the Markov
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
    # where loop_margins gives the reason under a related figure's name
    related = {
        "disk_margin_db": "disk_margin",
        "disk_margin_deg": "disk_margin",
        "crossover_rad_s": "phase_margin_deg",
    }
    for k in MARGIN_KEYS:
        v = out.get(k)
        if v is None or (isinstance(v, list) and not v and k == "closed_loop_poles"):
            out[k] = None
            if k == "closed_loop_poles":
                reasons.setdefault(k, "the closed loop has no poles (a static loop)")
            reasons.setdefault(k, reasons.get(related.get(k, k), "not computed by loop_margins"))
    if out.get("natural_frequencies_hz") == []:
        out["natural_frequencies_hz"] = None
        reasons["natural_frequencies_hz"] = "no oscillatory closed-loop pole"
    out["reasons"] = reasons
    return out


def _grid_change(points: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The first change of stability along a root-locus grid: the grid values on either side
    (``{"from": value, "to": value, "becomes": "unstable" | "stable"}``), None if the stability
    does not change on the grid."""
    for a, b in zip(points, points[1:], strict=False):
        if a["stable"] != b["stable"]:
            return {
                "from": a["value"],
                "to": b["value"],
                "becomes": "stable" if b["stable"] else "unstable",
            }
    return None


def _judder(op: OperatingPoint, ctrl: Any, cl: ClutchLoop) -> dict[str, Any]:
    """The judder threshold: numerically on any model (:func:`judder_crossing`, the first crossing
    of the re-linearised loop's poles over mu') and the closed form where it exists (reduced
    model, continuous controller); each None with a reason when it cannot be computed."""
    jc = judder_crossing(op, ctrl)
    out: dict[str, Any] = {"numeric": jc.to_dict(), "summary": jc.summary()}
    closed: dict[str, Any] | None = None
    why: str | None = None
    if op.kind != "reduced":
        why = (
            f"the closed form is derived on the reduced model (this is the {op.kind} model); "
            "see the numeric threshold"
        )
    elif ctrl.is_discrete:
        why = "the closed form needs a continuous controller (this one is sampled)"
    else:
        try:
            closed = _judder_threshold(cl.op, cl.engine, cl.L).to_dict()
        except (ValueError, ArithmeticError) as exc:
            why = f"the closed form failed: {exc}"
    out["closed_form"] = closed
    out["closed_form_reason"] = why
    return out


def _slip_root_loci(op: OperatingPoint, ctrl: Any, cl: ClutchLoop) -> dict[str, Any]:
    """Root loci over the controller gain (k_r for law 6) and over the clutch friction slope,
    and the judder threshold (``out["judder"]``)."""
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
    out["gain"]["grid_change"] = _grid_change(out["gain"]["points"])
    # physical parameter: the clutch friction slope mu' (judder), through the threshold
    judder = _judder(op, ctrl, cl)
    crit = judder["numeric"]["mu_slope_crit"]
    span = 1.5 * crit if crit is not None else -MU_SLOPE_SPAN_S_RAD
    vals = [float(v) for v in np.linspace(0.0, span, N_MU_SLOPE)]
    if not ctrl.is_discrete:
        d = root_locus(op, ctrl, parameter="mu_slope", values=vals).to_dict()
        d.pop("crossing", None)  # interpolated between grid points; the threshold is exact
    else:
        pts = []
        for v in vals:
            sys_v = linearise(op, inputs=("x_c",), mu_slope=v)
            ps = poles_of(_sampled_loop_poles(sys_v, op, ctrl), cl.dt)
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
    d["grid_change"] = _grid_change(d["points"])
    d["judder_mu_slope_crit"] = crit
    d["judder_reason"] = judder["numeric"]["reason"]
    d["span_reason"] = (
        None
        if crit is not None
        else f"no threshold to centre the grid on: the default span [{-MU_SLOPE_SPAN_S_RAD:g}, 0]"
    )
    es = cl.engine
    d["nominal"] = es.mu_slope_torque / es.k13 if es.k13 > 0 else None
    if d["nominal"] is None:
        d["nominal_reason"] = f"k13 = {es.k13:g} N m: no friction slope to refer to"
    out["mu_slope"] = d
    out["judder"] = judder
    return out


def _slip_point(res: Any, dtr: Drivetrain, start: float) -> OperatingPoint:
    return slip_point_after_start(res, dtr, start, delay=SLIP_DELAY_S)


def _lock_point(
    res: Any, dtr: Drivetrain, lock_t: float | None
) -> tuple[OperatingPoint | None, str]:
    T = np.asarray(res.t)
    if lock_t is None:
        return None, "no lock-up in the simulated scenario"
    v = float(np.interp(lock_t, T, res.state("v_vehicle")))
    try:
        op = locked_trim(dtr, vehicle_speed_kmh=v * M_S_TO_KMH)
        return op, f"locked_trim at the lock-up vehicle speed {v * M_S_TO_KMH:.4g} km/h"
    except (ValueError, RuntimeError) as exc:
        t = min(lock_t + 0.5, float(T[-1]))
        op = operating_point_from_result(res, t, drivetrain=dtr)
        if op.clutch_mode != "stuck":
            return None, f"locked_trim failed ({exc}) and the clutch is not stuck at t = {t:.4g} s"
        return op, f"trajectory at t = {t:.4g} s (locked_trim failed: {exc})"


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
    params: DrivetrainParams,
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
        "x_r_m": list(map(float, np.interp(t, T, np.asarray(res.extras["controller_command"])))),
        "control_start_s": float(sc.start_time),
        "v_vehicle_kmh": list(map(float, np.interp(t, T, res.state("v_vehicle")) * M_S_TO_KMH)),
        "driven_state": driven,
    }


def analyse_controller(
    *,
    controller: str | Path | ControllerSpec = "paper",
    params: str | Path | DrivetrainParams | None = None,
    model: str = "reduced",
    scenario: str | Path | Scenario = "paper-start",
) -> dict[str, Any]:
    """The data of a controller report: ``controller`` (built-in name, TOML file or spec) on
    ``model`` (``"reduced"`` / ``"full"``) with parameter set ``params`` (None: default; a name or
    TOML path) in ``scenario`` (a closed-loop scenario: name, TOML file or :class:`Scenario`).
    Returns the JSON-ready dict that :func:`~drivetrain_ctrl.reporting.controller_report.render_report`
    writes and draws.

    Raises ValueError (ControllerError / ScenarioError / CaseError) naming the argument for a bad
    controller, model, parameter set or scenario.
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
    # the controller is built once (warnings included) and the step runs use copies of it
    run = simulate_case(Case(scenario=sc, params=p, model=kind, controller=spec))
    dtr, ctrl, res, metrics = run.drivetrain, run.controller, run.result, run.metrics
    assert ctrl is not None  # a closed-loop scenario with a spec
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
    loci = _slip_root_loci(op_s, ctrl, cl)
    slip_entry["judder"] = loci.pop("judder")
    slip_entry["root_locus"] = loci
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
                "modes": [list(em) for em in v.op.mode_names],
                "segments": [
                    [ti.name, int(r)]
                    for ti, r in zip(v.op.model.tables, v.op.mode.reg, strict=True)
                    if ti.region_names is None
                ],
                "duration_s": v.duration_s,
                "t_s": v.op.t,
                "n_states": v.sys.nstates,
                "natural_frequencies_hz": list(v.natural_frequencies_hz),
                "damping": list(v.damping),
            }
            for v in linearise_visited_modes(res, drivetrain=dtr, min_duration=VISITED_MIN_S)
        ],
    }
    return dict(json_ready(data))
