"""Exact values between steps (``res.sample``, ``t_eval``) and sparse recording (issue 19, items
4 and 5)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from drivetrain_ctrl import signals as sg
from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction, Spring
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.sim.simulator import SimulationOptions, simulate

K_S, D_S, T_AMP, W_IN = 400.0, 0.5, 10.0, 7.0


def _oscillator() -> Model:
    """Two unit inertias on a linear spring (K_S) and damper (D_S); a sine torque on the first."""
    return Model(
        Chain(
            bodies=(Body("a", 1.0, torque_input="T"), Body("b", 2.0)),
            couplings=(Coupling("c", spring=Spring.linear(K_S), damper=D_S),),
            inputs=("T",),
        )
    )


def _oscillator_reference(t_end: float):
    """The same system written plainly, integrated by scipy at rtol 1e-12."""

    def f(t, x):
        wa, wb, q = x
        tc = K_S * q + D_S * (wa - wb)
        return [T_AMP * math.sin(W_IN * t) - tc, tc / 2.0, wa - wb]

    return solve_ivp(
        f, (0.0, t_end), [3.0, 0.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True
    ).sol


def test_sample_between_steps_matches_a_tight_reference_where_interpolation_does_not():
    m = _oscillator()
    opts = SimulationOptions(h_max=0.02)
    res = simulate(
        m, np.array([3.0, 0.0, 0.0]), {"T": sg.sine(T_AMP, W_IN)}, t_end=2.0, options=opts
    )
    ref = _oscillator_reference(2.0)
    # the midpoints of the recorded steps: the farthest from any recorded sample
    tm = 0.5 * (res.t[:-1] + res.t[1:])
    s = res.sample(tm)
    assert np.array_equal(s.t, tm)
    err_dense = np.max(np.abs(s.x - ref(tm).T))
    err_lin = max(np.max(np.abs(np.interp(tm, res.t, res.x[:, j]) - ref(tm)[j])) for j in range(3))
    assert err_dense < 1e-6
    assert err_lin > 100 * err_dense
    # the recorded steps themselves are the same in the re-run (same steps, same events)
    s2 = res.sample(res.t)
    assert np.max(np.abs(s2.x - res.x)) < 1e-12
    assert s.stats["steps"] == res.stats["steps"]
    # energies too: the dissipated energy at the samples against the re-run's
    assert np.max(np.abs(s2.dissipated - res.dissipated)) < 1e-12


def test_sample_at_an_event_is_the_left_limit_and_respects_the_switch():
    """Capacity sin t while slipping (the issue-19 reproducer): slip+ until pi (slip speed
    10 - 2 (1 - cos t)), then open (constant speeds). At pi the left limit is stated."""
    m = Model(
        Chain(
            bodies=(Body("a", 1.0), Body("b", 1.0)),
            couplings=(Coupling("c", friction=Friction(capacity_input="fn", name="c")),),
            inputs=("fn",),
        )
    )
    res = simulate(m, np.array([10.0, 0.0]), {"fn": sg.sine(1.0, 1.0)}, t_end=4.0)
    t_ev = next(e.t for e in res.events if e.to_mode == "open")
    rng = np.random.default_rng(1)
    tt = np.sort(np.concatenate([rng.uniform(0.0, 4.0, 200), [t_ev]]))
    s = res.sample(tt)
    exact_a = np.where(tt <= t_ev, 10.0 - (1.0 - np.cos(np.minimum(tt, math.pi))), 8.0)
    assert np.max(np.abs(s.x[:, 0] - exact_a)) < 1e-8
    k = int(np.searchsorted(tt, t_ev))
    assert s.mode_series("c")[k] == "slip+"  # left limit: still slipping at the event time
    assert set(s.mode_series("c")[k + 1 :]) == {"open"}
    # the dataframe view of the same
    df = res.to_dataframe(t=[1.0, 2.0])
    assert df["t [s]"].tolist() == [1.0, 2.0]
    assert df["omega_a [rad/s]"].iloc[0] == pytest.approx(10.0 - (1.0 - math.cos(1.0)), abs=1e-9)


@pytest.mark.parametrize(
    ("t", "match"),
    [([0.5, 5.0], r"t\[1\] = 5.0 \[s\]: must be finite and within the run \[0, 4\] s"),
     ([np.nan], r"t\[0\] = nan"),
     ([], "non-empty")],
)  # fmt: skip
def test_sample_rejects_times_outside_the_run(t, match):
    m = _oscillator()
    res = simulate(m, np.array([3.0, 0.0, 0.0]), {"T": sg.sine(T_AMP, W_IN)}, t_end=4.0)
    with pytest.raises(ValueError, match=match):
        res.sample(t)


def test_t_eval_must_increase_and_excludes_record_every():
    m = _oscillator()
    u = {"T": sg.sine(T_AMP, W_IN)}
    x0 = np.array([3.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"t_eval\[2\] = 0.5 follows 1.0"):
        simulate(m, x0, u, t_end=1.0, t_eval=[0.0, 1.0, 0.5])
    with pytest.raises(ValueError, match="record_every = 3 with t_eval"):
        simulate(m, x0, u, t_end=1.0, t_eval=[0.5], options=SimulationOptions(record_every=3))
    with pytest.raises(ValueError, match="record_every = 0"):
        SimulationOptions(record_every=0)


def test_sparse_recording_keeps_events_energies_and_lockup():
    """A clutch start on the full drivetrain (the built-in engage-ramp scenario): every 20th
    step recorded; the events, the lock-up time and the integrated energies are the full
    recording's, bit for bit; the samples kept are a subset of the full recording's."""
    from drivetrain_ctrl.plant.drivetrain import full_model
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.run import run_scenario

    dt = full_model(default_params())
    sc = load_scenario("engage-ramp")
    full = run_scenario(sc, dt)
    sparse = run_scenario(sc, dt, options=SimulationOptions(record_every=20))
    assert sparse.events == full.events
    assert sparse.t.shape[0] < full.t.shape[0] / 5
    assert np.all(np.isin(sparse.t, full.t))
    i = np.searchsorted(full.t, sparse.t)
    assert np.array_equal(sparse.x, full.x[i]) and np.array_equal(
        sparse.dissipated, full.dissipated[i]
    )
    assert sparse.lockup_time() == full.lockup_time()
    assert sparse.t[-1] == full.t[-1] and sparse.energy_residual_rel == full.energy_residual_rel
