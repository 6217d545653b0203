"""The per-sample physics over a whole run (sim.series) equals the single-point kernels row by row,
and the figures of merit computed from it equal those of the row-by-row evaluation (issue 23
item 6: a study's per-sample cost)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.plant.model import Mode
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import load_scenario
from drivetrain_ctrl.sim import metrics as metrics_mod
from drivetrain_ctrl.sim.metrics import engagement_metrics, state_accelerations
from drivetrain_ctrl.sim.run import run_scenario
from drivetrain_ctrl.sim.simulator import SimulationOptions, SimulationResult

RUNS = [
    ("paper-start", "paper", "full"),
    ("paper-start", "pi", "reduced"),
    ("engage-ramp", None, "full"),
    ("engage-ramp", None, "reduced"),
    ("tip-in", None, "full"),
]


def _run(name: str, ctrl: str | None, kind: str, **opts: Any) -> tuple[Any, Any, SimulationResult]:
    sc = load_scenario(name)
    dt = sc.drivetrain(default_params(), kind=kind)
    options = SimulationOptions(**opts) if opts else None
    res = run_scenario(sc, dt, controller=ctrl, options=options)
    return sc, dt, res


def _loop_accelerations(res: SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    """The previous definition: Model.rhs row by row, the left limit in the previous mode."""
    model = res.model
    right = np.empty((res.t.shape[0], model.nx))
    left = np.empty_like(right)
    prev: Mode | None = None
    for i in range(res.t.shape[0]):
        mode = Mode(tuple(int(v) for v in res.fm[i]), tuple(int(v) for v in res.reg[i]))
        right[i] = model.rhs(res.x[i], res.u[i], mode)
        same = prev is None or prev == mode
        left[i] = right[i] if same else model.rhs(res.x[i], res.u[i], prev)
        prev = mode
    return right, left


def _loop_coupling_torques(res: SimulationResult) -> np.ndarray:
    D = res._data()
    out = np.empty((res.t.shape[0], D.ratio.shape[0]))
    for i in range(res.t.shape[0]):
        _, Lam = K.mode_matrices(D, res.fm[i])
        out[i] = K.coupling_torques(D, res.x[i], res.u[i], res.fm[i], res.reg[i], Lam)
    return out


def _close(a: np.ndarray, b: np.ndarray) -> None:
    """Equal to round-off, column by column relative to the column's scale."""
    assert a.shape == b.shape
    scale = np.max(np.abs(b), axis=0) + 1e-300
    assert np.max(np.abs(a - b) / scale) < 1e-13


@pytest.mark.parametrize(("name", "ctrl", "kind"), RUNS)
def test_whole_run_physics_equals_the_kernels_row_by_row(
    name: str, ctrl: str | None, kind: str
) -> None:
    _, _, res = _run(name, ctrl, kind)
    # the run has events, so the left limits differ from the right ones somewhere
    right, left = state_accelerations(res)
    r0, l0 = _loop_accelerations(res)
    assert np.any(l0 != r0)
    _close(right, r0)
    _close(left, l0)
    # the clutch both stuck and slipping (tip-in: locked throughout, its backlash crossed):
    # the constraint torque and the kinetic one
    assert np.any(res.fm[:, 0] == K.STUCK)
    assert np.any(res.fm[:, 0] != K.STUCK) or name == "tip-in"
    _close(res.coupling_torques(), _loop_coupling_torques(res))
    E0 = np.array([K.stored_energy(res.model.data, xi) for xi in res.x])
    _close(res.stored_energy()[:, None], E0[:, None])


def test_smoothed_coupling_torques_equal_the_kernels() -> None:
    _, _, res = _run("engage-ramp", None, "reduced", smoothing=0.5)
    _close(res.coupling_torques(), _loop_coupling_torques(res))


@pytest.mark.parametrize(("name", "ctrl", "kind"), RUNS[:3])
def test_metrics_equal_those_of_the_row_by_row_evaluation(
    name: str, ctrl: str | None, kind: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    sc, dt, res = _run(name, ctrl, kind)
    ref = sc.reference if sc.needs_controller else None
    fast = engagement_metrics(res, dt, start=sc.start_time, reference=ref)
    monkeypatch.setattr(metrics_mod, "state_accelerations", _loop_accelerations)
    monkeypatch.setattr(SimulationResult, "coupling_torques", _loop_coupling_torques)
    monkeypatch.setattr(
        SimulationResult,
        "stored_energy",
        lambda self: np.array([K.stored_energy(self.model.data, xi) for xi in self.x]),
    )
    slow = engagement_metrics(res, dt, start=sc.start_time, reference=ref)
    assert fast.keys() == slow.keys()
    for k, v in slow.items():
        if isinstance(v, float):
            assert fast[k] == pytest.approx(v, rel=1e-9, abs=1e-12), k
        else:
            assert fast[k] == v, k
    assert fast["lockup_time_s"] is not None


def _loop_crossings(res: SimulationResult, t0: float, t1: float) -> int:
    """The previous definition: walk the samples' mode names, count changes of contact side."""
    n = 0
    for ti in res.model.tables:
        if ti.region_names is None:
            continue
        side = 0
        for tk, name in zip(res.t, res.mode_series(ti.name), strict=True):
            s = 1 if name.endswith("+") else -1 if name.endswith("-") else 0
            if s != 0:
                if side != 0 and s != side and t0 <= tk <= t1:
                    n += 1
                side = s
    return n


@pytest.mark.parametrize("kind", ["full", "reduced"])
def test_backlash_crossings_equal_the_sample_walk(kind: str) -> None:
    _, _, res = _run("tip-in", None, kind)
    t_end = float(res.t[-1])
    windows = [(0.0, t_end), (0.3 * t_end, 0.6 * t_end), (0.5 * t_end, t_end)]
    counts = [metrics_mod._backlash_counts(res, a, b)[1] for a, b in windows]
    assert counts == [_loop_crossings(res, a, b) for a, b in windows]
    assert counts[0] > 0  # tip-in crosses the gap


def test_a_signal_on_an_array_equals_its_value_point_by_point() -> None:
    from drivetrain_ctrl.core.signals import Signal, _eval_pwl

    sig = Signal((0.0, 0.5, 0.5, 1.0, 2.0, 2.0), (1.0, 1.0, 3.0, 4.0, 2.0, -1.0))
    t = np.concatenate([[-1.0, 0.0, 0.5, 1.0, 2.0, 3.0], np.linspace(-0.5, 2.5, 301)])
    ts, vs = np.asarray(sig.times), np.asarray(sig.values)
    expected = np.array([_eval_pwl(ts, vs, tj, tj) for tj in t])
    np.testing.assert_array_equal(sig(t), expected)
    assert float(sig(0.5)) == 3.0 and np.ndim(sig(0.5)) == 0
