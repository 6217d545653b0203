"""Value tests of drivetrain_ctrl.linear.linearisation (issue 22 item 4): the transfer-function
conversions on hand-derived state-space models, the pole figures against their closed forms,
and the output rows of a linearisation against the model's own Jacobian
(``./dev mutate drivetrain_ctrl/linear/linearisation.py``)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import control
import numpy as np
import pytest

from drivetrain_ctrl.linear.linearisation import (
    _oscillatory,
    natural_frequency_damping,
    oscillatory_poles,
    ss_to_tf,
    trim_tf,
)
from drivetrain_ctrl.linear.operating_point import OperatingPoint

# (s + 1)(s + 2) = s^2 + 3 s + 2 in companion form
A2 = [[0.0, 1.0], [-2.0, -3.0]]
B2 = [[0.0], [1.0]]


def _coeffs(tf: control.TransferFunction, i: int = 0, j: int = 0) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(tf.num[i][j], dtype=float), np.asarray(tf.den[i][j], dtype=float)


def test_ss_to_tf_on_a_companion_form() -> None:
    # C = [5, 1]: (s + 5) / (s^2 + 3 s + 2); D = 0.5 adds 0.5 (s^2 + 3 s + 2)
    sys = control.ss(A2, B2, [[5.0, 1.0]], [[0.5]])
    num, den = _coeffs(ss_to_tf(sys))
    assert den == pytest.approx([1.0, 3.0, 2.0], abs=1e-12)
    assert num == pytest.approx([0.5, 2.5, 6.0], abs=1e-12)


def test_ss_to_tf_two_inputs_two_outputs_and_a_zero_entry() -> None:
    # x1' = -x1 + u1, x2' = -2 x2 + u2; y1 = x1, y2 = x1 + x2
    sys = control.ss(
        [[-1.0, 0.0], [0.0, -2.0]], np.eye(2), [[1.0, 0.0], [1.0, 1.0]], np.zeros((2, 2)), 0.0
    )
    tf = ss_to_tf(sys)
    assert (tf.noutputs, tf.ninputs) == (2, 2)
    for i, j, expected in [
        (0, 0, [1.0, 2.0]),  # (s + 2) / ((s + 1)(s + 2))
        (1, 0, [1.0, 2.0]),
        (1, 1, [1.0, 1.0]),
    ]:
        num, den = _coeffs(tf, i, j)
        assert den == pytest.approx([1.0, 3.0, 2.0], abs=1e-12)
        assert np.trim_zeros(num, "f") == pytest.approx(expected, abs=1e-12)
    num01, _ = _coeffs(tf, 0, 1)  # u2 does not reach y1: the numerator is exactly 0
    assert np.all(num01 == 0.0)


def test_ss_to_tf_keeps_names_and_sample_time() -> None:
    sys = control.ss(A2, B2, [[1.0, 0.0]], [[0.0]], 0.01, inputs=["u"], outputs=["y"], name="p")
    tf = ss_to_tf(sys)
    assert tf.dt == 0.01 and tf.input_labels == ["u"] and tf.output_labels == ["y"]
    assert tf.name == "p"


def test_trim_tf_drops_the_round_off_leading_coefficients() -> None:
    # y = x1: 1 / (s^2 + 3 s + 2), a relative degree 2 (D = 0 and C B = 0)
    sys = control.ss(A2, B2, [[1.0, 0.0]], [[0.0]])
    num, den = _coeffs(trim_tf(sys))
    assert num.tolist() == pytest.approx([1.0], abs=1e-12) and num.size == 1
    assert den == pytest.approx([1.0, 3.0, 2.0], abs=1e-12)
    # y = x2 = s / (s^2 + 3 s + 2): C B = 1, one leading zero (D) dropped, the trailing 0 kept
    num, _ = _coeffs(trim_tf(control.ss(A2, B2, [[0.0, 1.0]], [[0.0]])))
    assert num.size == 2 and num == pytest.approx([1.0, 0.0], abs=1e-12)


def test_trim_tf_keeps_a_small_but_real_leading_coefficient() -> None:
    # y = 1e-9 x2 + x1: num = 1e-9 s + 1; C B = 1e-9 is not zero at its round-off scale
    sys = control.ss(A2, B2, [[1.0, 1e-9]], [[0.0]])
    num, _ = _coeffs(trim_tf(sys))
    assert num.size == 2 and num[0] == pytest.approx(1e-9, rel=1e-6)
    # a feedthrough D = 1e-9 is kept too
    num, _ = _coeffs(trim_tf(control.ss(A2, B2, [[1.0, 0.0]], [[1e-9]])))
    assert num.size == 3 and num[0] == pytest.approx(1e-9, rel=1e-9)


def test_trim_tf_on_a_delayed_discrete_system() -> None:
    # x1[k+1] = x2[k], x2[k+1] = u[k], y = x1: 1 / z^2 (two samples of delay)
    sys = control.ss([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], 0.1)
    tf = trim_tf(sys)
    num, den = _coeffs(tf)
    assert num.tolist() == [1.0]
    assert den == pytest.approx([1.0, 0.0, 0.0], abs=1e-15)
    assert tf.dt == 0.1


def test_trim_tf_passes_a_static_gain_and_a_tf_through() -> None:
    g = trim_tf(control.ss([], [], [], [[2.0]]))
    assert _coeffs(g)[0] == pytest.approx([2.0])
    h = control.tf([1.0, 2.0], [1.0, 3.0, 2.0])
    num, den = _coeffs(trim_tf(h))
    assert num == pytest.approx([1.0, 2.0]) and den == pytest.approx([1.0, 3.0, 2.0])


def test_natural_frequency_and_damping() -> None:
    fn, zeta = natural_frequency_damping(complex(-3.0, 4.0))
    assert fn == pytest.approx(5.0 / (2.0 * math.pi), rel=1e-15)
    assert zeta == pytest.approx(0.6, rel=1e-15)
    fn, zeta = natural_frequency_damping(complex(1.0, 0.0))
    assert (fn, zeta) == (pytest.approx(1.0 / (2.0 * math.pi)), pytest.approx(-1.0))
    assert natural_frequency_damping(0j) == (0.0, 1.0)


def test_oscillatory_poles_one_of_each_pair_sorted_by_modulus() -> None:
    poles = [-3 + 10j, -3 - 10j, -5.0, -1 + 2j, -1 - 2j, -7 + 1e-12j, 1e-10j]
    assert oscillatory_poles(poles) == [-1 + 2j, -3 + 10j]
    # the round-off threshold scales with |p| above 1: 1e-9 |p|
    assert oscillatory_poles([-1e6 + 5e-4j]) == []
    assert oscillatory_poles([-1e6 + 2e-3j]) == [-1e6 + 2e-3j]
    assert oscillatory_poles([-0.5 + 2e-9j]) == [-0.5 + 2e-9j]
    assert oscillatory_poles(np.array([[-1 + 1j]])) == [-1 + 1j]


def test_shuffle_mode_figures() -> None:
    (m,) = _oscillatory(np.array([-3 + 4j, -3 - 4j, -2.0]))
    assert (m.real, m.imag) == (-3.0, 4.0)
    assert m.natural_frequency_hz == pytest.approx(5.0 / (2.0 * math.pi), rel=1e-15)
    assert m.damped_frequency_hz == pytest.approx(4.0 / (2.0 * math.pi), rel=1e-15)
    assert m.damping == pytest.approx(0.6, rel=1e-15)


def test_visited_mode_durations_add_up_to_the_run() -> None:
    from drivetrain_ctrl.linear.linearisation import linearise_visited_modes
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.run import run_scenario

    sc = load_scenario("paper-start")
    dtr = sc.drivetrain(default_params(), kind="reduced")
    res = run_scenario(sc, dtr, controller="paper")
    vm = linearise_visited_modes(res, drivetrain=dtr, min_duration=0.0)
    t = np.asarray(res.t)
    # every sample interval belongs to the mode of its first sample: the durations tile the run
    assert sum(v.duration_s for v in vm) == pytest.approx(t[-1] - t[0], rel=1e-12)
    durations = [v.duration_s for v in vm]
    assert durations == sorted(durations, reverse=True)
    # a minimum duration drops exactly the shorter modes
    cut = durations[1]
    assert [
        v.duration_s for v in linearise_visited_modes(res, drivetrain=dtr, min_duration=cut)
    ] == [d for d in durations if d >= cut]


def test_each_visited_mode_is_linearised_in_the_middle_of_its_longest_interval() -> None:
    from drivetrain_ctrl.linear.linearisation import linearise_visited_modes
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.run import run_scenario

    sc = load_scenario("engage-ramp")
    dtr = sc.drivetrain(default_params(), kind="reduced")
    res = run_scenario(sc, dtr)
    t = np.asarray(res.t)
    keys = [
        (tuple(f), tuple(r))
        for f, r in zip(np.asarray(res.fm).tolist(), np.asarray(res.reg).tolist(), strict=True)
    ]
    # runs of equal keys; the interval of a run ends at the first sample of the next one (or
    # at the end); per key the longest interval
    longest: dict[object, tuple[float, float]] = {}
    i = 0
    while i < len(t) - 1:
        j = i
        while j + 1 < len(t) - 1 and keys[j + 1] == keys[i]:
            j += 1
        t0, t1 = float(t[i]), float(t[j + 1])
        best = longest.get(keys[i], (0.0, 0.0))
        if t1 - t0 > best[1] - best[0]:
            longest[keys[i]] = (t0, t1)
        i = j + 1
    vm = linearise_visited_modes(res, drivetrain=dtr, min_duration=0.0)
    mids = sorted(0.5 * (a + b) for a, b in longest.values())
    assert sorted(float(v.op.t or 0.0) for v in vm) == pytest.approx(mids, rel=1e-12)


def test_a_mode_held_only_in_the_last_sample_interval_is_visited() -> None:
    from drivetrain_ctrl.linear.linearisation import linearise_visited_modes
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.run import run_scenario

    sc = load_scenario("engage-ramp")
    dtr = sc.drivetrain(default_params(), kind="reduced")
    t_lock = run_scenario(sc, dtr).stuck_phases("clutch")[0][0]
    # stop 20 us after lock-up: the locked mode holds only the run's last sample interval
    res = run_scenario(sc, dtr, t_end=t_lock + 2e-5)
    t = np.asarray(res.t)
    fm = [tuple(r) for r in np.asarray(res.fm).tolist()]
    assert fm[-1] == fm[-2] != fm[-3]  # the last mode starts at the last-but-one sample
    vm = linearise_visited_modes(res, drivetrain=dtr, min_duration=0.0)
    assert sum(v.duration_s for v in vm) == pytest.approx(t[-1] - t[0], rel=1e-12)
    assert any("clutch=stuck" in v.label for v in vm)


def _locked_op() -> OperatingPoint:
    from drivetrain_ctrl.linear.operating_point import locked_trim
    from drivetrain_ctrl.plant.drivetrain import reduced_model
    from drivetrain_ctrl.plant.params import default_params

    return locked_trim(reduced_model(default_params()), vehicle_speed_kmh=30.0, slope=0.03)


def test_the_jacobians_of_an_operating_point_are_computed_once() -> None:
    """An operating point is immutable: its Jacobians are kept and handed out again."""
    from drivetrain_ctrl.linear.linearisation import linearisation_parts

    op = _locked_op()
    first = linearisation_parts(op)
    assert linearisation_parts(op) is first
    assert linearisation_parts(_locked_op()) is not first


def test_engine_torque_and_vehicle_acceleration_output_rows() -> None:
    """C_1 = K lag - b1 omega_1 - c1 (paper, Sec. II): its row is K on the lag state and -b1 on
    the engine speed, no feedthrough; a_vehicle's row is the vehicle speed's row of A and B."""
    from drivetrain_ctrl.linear.linearisation import linearise
    from drivetrain_ctrl.plant.params import default_params

    e = default_params().engine
    op = _locked_op()
    sys = linearise(op, outputs=["C_1", "a_vehicle"], reduce=False)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    states = list(sys.state_labels)
    want = np.zeros(len(states))
    want[states.index("lag_engine")] = e.K
    want[states.index("omega_engine")] = -e.b1
    assert C[0] == pytest.approx(want, abs=1e-12 * e.K)
    assert np.all(D[0] == 0.0)
    iv = states.index("v_vehicle")
    assert np.any(A[iv] != 0.0)
    assert np.array_equal(C[1], A[iv]) and np.array_equal(D[1], B[iv])


def test_trim_tf_keeps_a_zero_transfer_function() -> None:
    """An input that reaches no output: the numerator stays one zero coefficient."""
    sys = control.ss(A2, [[0.0], [0.0]], [[1.0, 0.0]], [[0.0]])
    num, den = _coeffs(trim_tf(sys))
    assert num.size >= 1 and np.all(num == 0.0)
    assert den.tolist() == [1.0]


def test_visited_modes_per_key_durations_and_longest_intervals_full_model() -> None:
    """On the full model's engage-ramp (backlash chatter: many short modes), each sample
    interval [t_i, t_i+1] belongs to the mode of sample i; per mode the total time, and the
    first of its longest maximal runs of intervals, whose middle is the operating point."""
    from drivetrain_ctrl.linear.linearisation import linearise_visited_modes
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.run import run_scenario

    sc = load_scenario("engage-ramp")
    dtr = sc.drivetrain(default_params(), kind="full")
    res = run_scenario(sc, dtr)
    t = np.asarray(res.t)
    fm, reg = np.asarray(res.fm).tolist(), np.asarray(res.reg).tolist()
    keys = [(tuple(f), tuple(r)) for f, r in zip(fm, reg, strict=True)]
    total: dict[object, float] = {}
    best: dict[object, tuple[float, float]] = {}
    run_start = 0
    for i in range(len(t) - 1):
        total[keys[i]] = total.get(keys[i], 0.0) + float(t[i + 1] - t[i])
        last_of_run = i == len(t) - 2 or keys[i + 1] != keys[i]
        if last_of_run:
            t0, t1 = float(t[run_start]), float(t[i + 1])
            b = best.get(keys[i])
            if (b is None and t1 > t0) or (b is not None and t1 - t0 > b[1] - b[0]):
                best[keys[i]] = (t0, t1)
            run_start = i + 1
    assert len(total) > 5
    vm = linearise_visited_modes(res, drivetrain=dtr, min_duration=0.0)
    got = {(tuple(v.op.mode.fm), tuple(v.op.mode.reg)): v for v in vm}
    assert set(got) == {k for k in total if k in best}
    for k, v in got.items():
        assert v.duration_s == pytest.approx(total[k], rel=1e-12, abs=1e-15)
        assert v.op.t == pytest.approx(0.5 * (best[k][0] + best[k][1]), rel=1e-12)


def test_a_shuffle_mode_is_immutable_and_slotted() -> None:
    import dataclasses

    (m,) = _oscillatory(np.array([-3 + 4j, -3 - 4j]))
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.real = 0.0  # type: ignore[misc]
    assert not hasattr(m, "__dict__")


def _engage_ramp_reduced(t_end: float | None = None) -> tuple[Any, Any]:
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.run import run_scenario

    sc = load_scenario("engage-ramp")
    dtr = sc.drivetrain(default_params(), kind="reduced")
    return run_scenario(sc, dtr, t_end=t_end), dtr


def test_a_run_in_one_mode_is_linearised_in_its_middle() -> None:
    """Before the pedal moves the run holds one mode: one visited mode, the whole run long,
    linearised at the run's middle (its last sample interval included)."""
    from drivetrain_ctrl.linear.linearisation import linearise_visited_modes

    res, dtr = _engage_ramp_reduced(t_end=0.1)
    t = np.asarray(res.t)
    assert len({tuple(r) for r in np.asarray(res.fm).tolist()}) == 1
    assert t.size > 3 and t[-1] > t[-2]
    (v,) = linearise_visited_modes(res, drivetrain=dtr, min_duration=0.0)
    assert v.duration_s == pytest.approx(t[-1] - t[0], rel=1e-14)
    assert v.op.t == pytest.approx(0.5 * (t[0] + t[-1]), rel=1e-14)


def test_a_mode_held_for_no_time_is_not_visited() -> None:
    """An event is recorded as two samples about 1e-15 s apart; with the two made simultaneous
    and a mode given only to the first of them (edited in), that mode is held for no time and
    is not visited, even with ``min_duration = 0``."""
    from drivetrain_ctrl.linear.linearisation import linearise_visited_modes

    res, dtr = _engage_ramp_reduced()
    t = np.asarray(res.t).copy()
    i = int(np.flatnonzero(np.diff(t[:-1]) < 1e-12)[0])
    t[i + 1] = t[i]
    fm = np.asarray(res.fm).copy()
    seen = {tuple(r) for r in fm.tolist()}
    novel = next(
        c
        for c in ([a, b, *fm[i, 2:].tolist()] for a in (0, 1, 2, 3) for b in (0, 1, 2, 3))
        if tuple(c) not in seen
    )
    fm[i] = novel
    base = dataclasses.replace(res, t=t)
    edited = dataclasses.replace(res, t=t, fm=fm)
    want = linearise_visited_modes(base, drivetrain=dtr, min_duration=0.0)
    got = linearise_visited_modes(edited, drivetrain=dtr, min_duration=0.0)
    assert [v.label for v in got] == [v.label for v in want]
    assert [v.duration_s for v in got] == pytest.approx([v.duration_s for v in want], rel=1e-12)
