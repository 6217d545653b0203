"""Value tests of design/hinf.py (issue 22 item 4: mutation score of the design modules): the
reference frequency w_ref of the module docstring (bandwidth, prewarped for a sampled set; else
where |W1| falls to 1; else the log-middle of the nominal plant's grid), and the axis-pole shift
of a static system."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from drivetrain_ctrl.design.hinf import (
    HinfSpec,
    _reference_frequency,
    _unity_crossing,
    hinf_mixsyn,
    shift_axis_poles,
)
from drivetrain_ctrl.design.plants import Plant, frequency_grid

s = control.tf("s")


def test_unity_crossing_of_a_first_order_weight() -> None:
    """|10/(j w + 1)| = 1 at w = sqrt(99); on the 2000-point log grid from 0.01 to 1000 rad/s
    the crossing is reported at the grid point at or just below it (one step is a factor
    10^(5/1999)). A weight below 1 everywhere has no crossing."""
    w = _unity_crossing(control.ss(10 / (s + 1)), 0.01, 1000.0)
    step = 10 ** (5 / 1999)
    assert w is not None and math.sqrt(99) / step < w <= math.sqrt(99)
    assert _unity_crossing(control.ss(0.5 / (s + 1)), 0.01, 1000.0) is None
    # |0.1 (s + 1)| rises through 1 at sqrt(99) too
    up = _unity_crossing(control.ss(control.tf([0.1, 0.1], [1e-6, 1.0])), 0.01, 1000.0)
    assert up is not None and math.sqrt(99) / step < up <= math.sqrt(99) * step


def test_reference_frequency_rules() -> None:
    nom = Plant(1 / ((s + 1) * (0.1 * s + 1)))
    # 1. the bandwidth
    assert _reference_frequency(HinfSpec(bandwidth=3.0), nom, 0.0) == 3.0
    # ... prewarped for a sampled set: 2/dt tan(w dt/2)
    dt = 0.05
    got = _reference_frequency(HinfSpec(bandwidth=3.0), nom, dt)
    assert got == pytest.approx(2 / dt * math.tan(3.0 * dt / 2), rel=1e-14)
    with pytest.raises(ValueError, match="must be below the Nyquist frequency"):
        _reference_frequency(HinfSpec(bandwidth=math.pi / dt), nom, dt)
    # 2. where |W1| falls to 1 (W1 = (s/2 + 5)/(s + 0.05): |W1| = 1 at w^2 = (25 - 0.0025)/0.75)
    W1 = (s / 2 + 5) / (s + 0.05)
    w1 = math.sqrt((25 - 0.0025) / 0.75)
    got = _reference_frequency(HinfSpec(W1=W1), nom, 0.0)
    g0 = frequency_grid(nom, n=50)
    step = (g0[-1] * 100 / (g0[0] / 100)) ** (1 / 1999)
    assert w1 / step < got <= w1
    # 3. no bandwidth, W1 never reaching 1 (or no W1): the log-middle of the plant's grid
    mid = math.sqrt(g0[0] * g0[-1])
    assert _reference_frequency(HinfSpec(W2=control.tf([0.1], [1.0])), nom, 0.0) == pytest.approx(
        mid, rel=1e-14
    )
    assert _reference_frequency(
        HinfSpec(W1=control.tf([0.5], [1.0, 1.0])), nom, 0.0
    ) == pytest.approx(mid, rel=1e-14)
    # ... warped for a sampled set, 2/dt tan(min(mid dt/2, 1.4))
    nd = Plant(control.c2d(1 / ((s + 1) * (0.1 * s + 1)), dt))
    gd = frequency_grid(nd, n=50)
    midd = math.sqrt(gd[0] * gd[-1])
    want = 2 / dt * math.tan(min(midd * dt / 2, 1.4))
    assert _reference_frequency(HinfSpec(W2=control.tf([0.1], [1.0])), nd, dt) == pytest.approx(
        want, rel=1e-14
    )


def test_shift_axis_poles_of_a_static_system() -> None:
    """No states: nothing to shift, the system itself and 0 poles moved."""
    G, k = shift_axis_poles(control.ss([], [], [], [[2.5]]), 0.1)
    assert k == 0 and G.nstates == 0 and float(np.asarray(G.D)[0, 0]) == 2.5


def test_axis_tolerance_is_relative_above_one_rad_s() -> None:
    """The default tolerance for "on the imaginary axis" is 1e-9 max(1, |p|): a pole at
    -0.5e-9 is moved, one at -1.5e-9 is not (|p| < 1, so the tolerance is 1e-9); a pole at
    -1.5e-9 + 2j is (|p| = 2: tolerance 2e-9). shift = 0 is refused."""
    for re_p, moved in ((-0.5e-9, 1), (-1.5e-9, 0)):
        G, k = shift_axis_poles(control.ss([[re_p]], [[1.0]], [[1.0]], [[0.0]]), 0.1)
        assert k == moved
        assert float(np.asarray(G.A)[0, 0]) == pytest.approx(re_p - 0.1 * moved, abs=1e-15)
    A = np.array([[-1.5e-9, 2.0], [-2.0, -1.5e-9]])
    _, k = shift_axis_poles(control.ss(A, [[1.0], [0.0]], [[1.0, 0.0]], [[0.0]]), 0.1)
    assert k == 2
    with pytest.raises(ValueError, match=r"shift = 0.0: must be > 0"):
        shift_axis_poles(control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]]), 0.0)


def test_spec_bounds_are_open_or_closed_as_documented() -> None:
    """bandwidth > 0 (any positive value, 0.5 included), low_frequency_gain in (0, 1],
    check_points >= 50 (50 accepted); mixsyn_weights' mt > 1 (1 refused)."""
    from drivetrain_ctrl.design.hinf import mixsyn_weights

    assert HinfSpec(bandwidth=0.5).bandwidth == 0.5
    assert HinfSpec(check_points=50).check_points == 50
    assert HinfSpec(low_frequency_gain=1.0).low_frequency_gain == 1.0
    with pytest.raises(ValueError, match=r"low_frequency_gain = 0.0: must be > 0"):
        HinfSpec(low_frequency_gain=0.0)
    with pytest.raises(ValueError, match=r"check_points = 49"):
        HinfSpec(check_points=49)
    with pytest.raises(ValueError, match=r"mt = 1.0: must be > 1"):
        mixsyn_weights(1 / (s + 1), bandwidth=1.0, mt=1.0)
    w = mixsyn_weights(1 / (s + 1), bandwidth=1.0, mt=1.25)
    assert w.W3 is not None and float(np.asarray(w.W3.D)[0, 0]) == pytest.approx(0.8)


def test_snap_moves_real_slow_poles_to_zero_and_keeps_a_complex_pair() -> None:
    """An upper-triangular slow part: its diagonal (the real poles) set to 0, the rest kept
    (True); a 2x2 block with a nonzero sub-diagonal (a complex pair) is returned as it is
    (False)."""
    from drivetrain_ctrl.design.hinf import _snap

    A = np.array([[-1e-4, 0.3], [0.0, -2e-4]])
    Ks, ok = _snap(control.ss(A, [[1.0], [1.0]], [[1.0, 2.0]], [[0.0]]))
    assert ok and np.array_equal(np.asarray(Ks.A), np.array([[0.0, 0.3], [0.0, 0.0]]))
    Ac = np.array([[-1e-4, 1e-3], [-1e-3, -1e-4]])
    Kc, ok = _snap(control.ss(Ac, [[1.0], [0.0]], [[1.0, 0.0]], [[0.0]]))
    assert not ok and np.array_equal(np.asarray(Kc.A), Ac)


class _OnlyHere:
    """An object the script (a fresh, isolated interpreter) cannot unpickle: its class lives in
    this test module."""


def test_script_failure_reports_the_last_line_of_its_error() -> None:
    """The synthesis run as a script on arguments it cannot even unpickle: finished, no result,
    and the exit code with the last line of the error output (the exception)."""
    from drivetrain_ctrl.design.hinf import _run_script

    done, msg, how = _run_script((_OnlyHere(),), 60.0)
    assert done and msg is None
    assert how.startswith("exit code 1 ") and "Error: No module named" in how


def test_automatic_order_is_the_smallest_within_the_reduction_tolerance() -> None:
    """exp(-0.1 s)/(s + 1), bandwidth 2 rad/s: the full controller has 5 states; order 4 (the
    only lower order near it) weighs 1.05 to 1.2 times the full-order norm, orders 1-3 far
    more. With reduction_tol = 0.05 (the default) the full order is kept, with 0.2 order 4 is
    taken; a continuous design's controllers are saved with dt = 0."""
    P = Plant(1 / (s + 1), delay=0.1)
    d = hinf_mixsyn(P, bandwidth=2.0)
    d4 = hinf_mixsyn(P, bandwidth=2.0, reduction_tol=0.2)
    ref = max(d.gamma, d.norm_reduced)
    assert d.order_full == 5 and d.order_reduced == 5
    assert 1.05 * ref < d4.norm_reduced <= 1.2 * ref and d4.order_reduced == 4
    assert d.to_dict()["controller_reduced"]["dt"] == 0.0


def test_in_a_daemonic_process_the_synthesis_runs_as_a_script(monkeypatch) -> None:  # noqa: ANN001
    """A daemonic process (a pool or Dask worker) may not fork children: _can_fork says so and
    the synthesis runs in a fresh interpreter instead, with the same optimum as the forked run
    (forking there fails: "daemonic processes are not allowed to have children")."""
    import multiprocessing as mp

    from drivetrain_ctrl.design.hinf import _can_fork

    assert _can_fork()  # Linux, a normal process
    forked = hinf_mixsyn(control.tf([1.0], [1.0, 1.0]), bandwidth=5.0)
    monkeypatch.setitem(mp.current_process()._config, "daemon", True)  # type: ignore[attr-defined]
    assert not _can_fork()
    d = hinf_mixsyn(control.tf([1.0], [1.0, 1.0]), bandwidth=5.0)
    assert d.gamma_optimal == pytest.approx(forked.gamma_optimal, rel=1e-9)
