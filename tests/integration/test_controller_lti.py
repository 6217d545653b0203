"""A general LTI law on the switching plant (issue 20 item 6): the PI written as ``law = "lti"``
runs the same trajectory as ``law = "pi"`` (which pins the semantics: signed error, offset,
anti-windup, latch, sampling and delay), and a controller file is used by path by the scenario
runner, the studies' cases and the controller report."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

from drivetrain_ctrl.control.laws import ControllerSpec, builtin_controllers, load_controller
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import load_scenario
from drivetrain_ctrl.sim.metrics import engagement_metrics
from drivetrain_ctrl.sim.run import run_scenario
from drivetrain_ctrl.studies.case import Case, simulate_case

P = default_params()
SC = load_scenario("paper-start", params=P)


def _run(kind: str, ctl: object):  # type: ignore[no-untyped-def]
    dt = SC.drivetrain(P, kind=kind)
    res = run_scenario(SC, dt, controller=ctl)
    return res, engagement_metrics(res, dt, start=SC.start_time, reference=SC.reference)


def _pi_as_lti(base: str, form: str) -> ControllerSpec:
    """The built-in PI ``base`` as an ``"lti"`` law: continuous ``kp + ki/s``; sampled with the
    PI's forward-Euler integrator, ``kp + ki Ts/(z - 1)``, as num/den in z or as its state space
    ``x[k+1] = x[k] + Ts e[k], u = ki x + kp e``."""
    pi = builtin_controllers()[base]
    assert pi.kp is not None and pi.ki is not None
    ts = pi.sample_period_s
    common = dict(
        name=f"{base}-as-lti",
        law="lti",
        x_r0=pi.x_r0,
        sample_period_s=ts,
        delay_samples=pi.delay_samples,
    )
    if ts is None:
        return ControllerSpec(**common, num=[pi.kp, pi.ki], den=[1.0, 0.0])  # type: ignore[arg-type]
    if form == "tf":
        return ControllerSpec(**common, num=[pi.kp, pi.ki * ts - pi.kp], den=[1.0, -1.0])  # type: ignore[arg-type]
    return ControllerSpec(**common, A=[[1.0]], B=[ts], C=[pi.ki], D=pi.kp)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "base,form", [("pi", "tf"), ("pi-10ms", "ss")], ids=["continuous-tf", "sampled-ss"]
)
@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_pi_written_as_lti_runs_the_pi_trajectory_bitwise(
    base: str, form: str, kind: str, tmp_path: Path
) -> None:
    """Same realisation, same anti-windup time: the same floating-point operations, the same
    steps and events; loaded from its file by path."""
    spec = _pi_as_lti(base, form)
    path = spec.to_toml(tmp_path / "pi-lti.toml")
    res_pi, m_pi = _run(kind, base)
    res_lti, m_lti = _run(kind, str(path))
    assert res_lti.t.shape == res_pi.t.shape
    assert np.array_equal(res_lti.t, res_pi.t)
    assert np.array_equal(res_lti.x, res_pi.x)
    assert np.array_equal(res_lti.extras["controller_command"], res_pi.extras["controller_command"])
    assert res_lti.events == res_pi.events
    assert m_lti == m_pi
    assert m_pi["lockup_time_s"] is not None  # a real engagement, not two identical failures


def test_sampled_pi_written_as_z_transfer_function_agrees_to_round_off() -> None:
    """num/den in z realise the sampled PI with another state scaling (the state is Ts times
    the PI's): round-off differs, which may move an event by a few ulps; the engagement is the
    same."""
    res_pi, m_pi = _run("reduced", "pi-10ms")
    res_lti, m_lti = _run("reduced", _pi_as_lti("pi-10ms", "tf"))
    w_pi = res_pi.state("omega_engine")
    w_lti = np.interp(res_pi.t, res_lti.t, res_lti.state("omega_engine"))
    assert np.max(np.abs(w_lti - w_pi)) <= 1e-6 * np.max(np.abs(w_pi))
    assert m_lti["lockup_time_s"] == pytest.approx(m_pi["lockup_time_s"], abs=1e-9)
    assert m_lti["jerk_max_m_s3"] == pytest.approx(m_pi["jerk_max_m_s3"], rel=1e-6)


def test_controller_file_in_a_study_case_and_a_report(tmp_path: Path) -> None:
    """By path in a study case (picklable, run in a worker like any case) and in the controller
    report, whose first section shows the design provenance."""
    from drivetrain_ctrl.reporting.controller_analysis import analyse_controller
    from drivetrain_ctrl.reporting.controller_report import _sections

    design = {"method": "by hand", "spec": {"ms": 1.4, "plants": ["nominal"]}}
    spec = ControllerSpec(
        name="pi-lti", law="lti", num=[1.0e-3, 5.0e-3], den=[1.0, 0.0], x_r0=0.07, design=design
    )
    path = spec.to_toml(tmp_path / "pi-lti.toml")
    case = Case(scenario="paper-start", model="reduced", controller=str(path))
    rec = simulate_case(pickle.loads(pickle.dumps(case)))
    res_pi, _ = _run("reduced", "pi")
    assert np.array_equal(rec.result.x, res_pi.x)
    data = analyse_controller(controller=str(path), model="reduced")
    assert data["inputs"]["controller"] == spec.to_dict()
    assert load_controller(path) == spec
    paras = _sections(data)[0][1]
    assert (
        "Design (provenance: the controller file's [design] table): method = by hand; "
        in (paras[1])
    )
    assert "spec.ms = 1.4" in paras[1] and "spec.plants = [nominal]" in paras[1]
