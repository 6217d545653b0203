"""Value tests of design/robust.py (issue 22 item 4: mutation score of the design modules): the
feasibility tolerance of a given start against a slack computed by hand, and the grid refinement
around the active cells against the module docstring's rule (cells split in four, log-equal)."""

from __future__ import annotations

import control
import numpy as np
import pytest

from drivetrain_ctrl.design.plants import Plant
from drivetrain_ctrl.design.robust import InfeasibleSpecError, robust_pi

s = control.tf("s")


@pytest.mark.parametrize(("excess", "verdict"), [(1.5e-7, "does not meet"), (0.5e-7, "stabilise")])
def test_a_given_start_is_checked_to_the_feasibility_tolerance(excess: float, verdict: str) -> None:
    """P = -1 (static), start kp = 0.5 (1 + e), ki = 1e-12: L = -kp - ki/(j w), so |1 + L| =
    0.5 (1 - e) up to 1e-12 at every frequency, and the relative slack of |S| <= 2, (|1 + L| -
    1/2) / (1/2), is -e. The start is rejected for e = 1.5e-7 (beyond the documented 1e-7
    tolerance); for e = 0.5e-7 it passes that check and fails the next one: the closed loop's
    pole ki / (1 - kp) > 0 is unstable."""
    with pytest.raises(InfeasibleSpecError, match=verdict):
        robust_pi(
            control.tf([-1.0], [1.0]),
            start=(0.5 * (1.0 + excess), 1e-12),
            omega=tuple(np.logspace(0, 1, 20)),
            ms=2.0,
        )


def test_the_grid_is_refined_around_the_active_cells() -> None:
    """One refinement round (the default): the design grid keeps every given point and splits
    a run of cells, the one where the Nyquist curve comes closest to -1 and its neighbours
    included, into four log-equal parts (three new points per cell); the message gives the new
    size. refine=0 keeps the grid."""
    w0 = np.logspace(-2, 2, 40)
    plant = Plant(1 / (s + 1), 0.5)
    r = robust_pi(plant, ms=1.4, omega=tuple(w0))
    assert np.all(np.isin(w0, r.omega))
    added = np.setdiff1d(r.omega, w0)
    assert added.size > 0
    cells, counts = np.unique(np.searchsorted(w0, added) - 1, return_counts=True)
    assert np.all(counts == 3)
    assert np.all(np.diff(cells) == 1) and cells.size >= 3  # one run of near cells, dilated
    for k in cells:
        lw = np.log(w0[k]) + (np.log(w0[k + 1]) - np.log(w0[k])) * np.array([0.25, 0.5, 0.75])
        got = added[(added > w0[k]) & (added < w0[k + 1])]
        assert got == pytest.approx(np.exp(lw), rel=1e-12)
    # the closest approach to -1 of the final loop (python-control, exact delay, dense grid)
    wd = np.logspace(-2, 2, 20001)
    mag, ph, _ = control.frequency_response(r.controller * plant.sys, wd)
    L = mag * np.exp(1j * ph) * np.exp(-0.5j * wd)
    k_min = int(np.searchsorted(w0, wd[int(np.argmin(np.abs(1 + L)))])) - 1
    assert {k_min - 1, k_min, k_min + 1} <= set(cells.tolist())
    assert r.message.endswith(f"grid refined around the active cells to {r.omega.size} points")
    assert r.omega.size == w0.size + 3 * cells.size
    r0 = robust_pi(plant, ms=1.4, omega=tuple(w0), refine=0)
    assert np.array_equal(r0.omega, w0) and "refined" not in r0.message


W0 = tuple(np.logspace(-2, 2, 40))


def _ks_peak(C: object, plant: Plant) -> float:
    """max |C / (1 + C P)| with the exact delay (python-control responses, dense grid)."""
    w = np.logspace(-3, 3, 20001)
    mc, pc, _ = control.frequency_response(C, w)
    mp, pp, _ = control.frequency_response(plant.sys, w)
    Cw = mc * np.exp(1j * pc)
    L = Cw * mp * np.exp(1j * pp) * np.exp(-1j * w * plant.delay)
    return float(np.max(np.abs(Cw / (1 + L))))


def test_the_effort_bound_has_the_same_optimum_with_and_without_the_working_set() -> None:
    """exp(-0.5 s)/(s + 1), Ms <= 1.4, |KS| <= 1.1 (binding: without it max |KS| = 1.21): the
    full problem (working_set=False, its cone rows built once) and the working-set one reach
    the same gains; the bound holds on a dense grid computed here."""
    plant = Plant(1 / (s + 1), 0.5)
    free = robust_pi(plant, ms=1.4, omega=W0)
    assert _ks_peak(free.controller, plant) > 1.2
    a = robust_pi(plant, ms=1.4, ks_max=1.1, omega=W0, working_set=True)
    b = robust_pi(plant, ms=1.4, ks_max=1.1, omega=W0, working_set=False)
    assert (b.kp, b.ki) == pytest.approx((a.kp, a.ki), rel=1e-6)
    assert a.ki < free.ki
    for r in (a, b):
        peak = _ks_peak(r.controller, plant)
        assert peak <= 1.1 * (1 + 1e-6) and peak > 1.09
        assert any(name == "ks" for p in r.plants for name, _w, _s in p.active)
        assert "|KS| <= 1.1" in r.summary()


def test_timings_are_parts_of_the_wall_time() -> None:
    """Each phase's time [s] is >= 0 and at most the design's wall-clock time; the solver's
    time is part of the iterations'."""
    r = robust_pi(Plant(1 / (s + 1), 0.5), ms=1.4, mt=1.3, omega=W0)
    t = dict(r.timings)
    assert set(t) == {"grid", "start", "iterations", "solver", "check"}
    assert all(0.0 <= v <= r.wall_time_s for v in t.values())
    assert r.solve_time_s == t["solver"] <= t["iterations"]
    assert "Ms <= 1.4, Mt <= 1.3:" in r.summary()
    assert "Mt <=" not in robust_pi(Plant(1 / (s + 1), 0.5), ms=1.4, omega=W0).summary()


def test_a_tuning_compares_equal_whatever_its_grid_array() -> None:
    """omega is left out of the comparison (an array has no single truth value): a copy of the
    result with an equal, separate grid array is equal to it."""
    import dataclasses

    r = robust_pi(Plant(1 / (s + 1), 0.5), ms=1.4, omega=W0)
    assert dataclasses.replace(r, omega=r.omega.copy()) == r


def test_spec_lower_bounds_are_as_documented() -> None:
    """ks_max > 0 (0.5 accepted, 0 refused); check_points >= 10 (10 accepted, 9 refused)."""
    from drivetrain_ctrl.design.robust import RobustSpec

    assert RobustSpec(ks_max=0.5).ks_max == 0.5
    assert RobustSpec(check_points=10).check_points == 10
    with pytest.raises(ValueError, match=r"ks_max = 0.0: must be > 0"):
        RobustSpec(ks_max=0.0)
    with pytest.raises(ValueError, match=r"check_points = 9: must be an integer >= 10"):
        RobustSpec(check_points=9)


def test_steps_at_the_trust_limit_are_unbounded_only_after_a_millionfold_growth() -> None:
    """From a start far below the optimum, ki = 1e-4, each convex step is at its trust limit:
    ki moves by trust times its size plus the 1e-3 floor, a factor 2.001, for more than five
    steps in a row. That is not an unbounded problem (ki grows about 4000-fold, not 1e6-fold):
    the iteration goes on to the optimum of the automatic start."""
    plant = Plant(1 / (s + 1), 0.5)
    auto = robust_pi(plant, ms=1.4, omega=W0)
    r = robust_pi(plant, ms=1.4, omega=W0, start=(0.1, 1e-4))
    ratios = np.array(r.ki_history[1:]) / np.array(r.ki_history[:-1])
    assert ratios[:6] == pytest.approx([2.001] * 6, rel=1e-9)
    assert r.converged and r.ki == pytest.approx(auto.ki, rel=1e-3)


def test_an_unbounded_problem_is_declared_at_a_millionfold_growth_of_ki() -> None:
    """1/(s + 1) without delay: Ms never limits the gains. From ki = 0.01 every step is at its
    trust limit (factor 2.001), and the error comes at the first step past 1e6 x 0.01 = 1e4,
    so the ki it names lies between 1e4 and 2.001e4."""
    import re

    from drivetrain_ctrl.design.robust import UnboundedSpecError

    with pytest.raises(UnboundedSpecError, match="without bound") as e:
        robust_pi(1 / (s + 1), ms=1.4, start=(0.1, 0.01), omega=W0)
    m = re.search(r"from 0\.01 to ([0-9.e+]+),", str(e.value))
    assert m is not None and 1e4 < float(m.group(1)) <= 2.001e4


def test_the_automatic_start_gives_up_after_25_unstable_candidates() -> None:
    """1/((s - 0.5)(s + 2)), open-loop unstable: the largest-ki members of the start family that
    meet |S| <= 2 on the grid do not stabilise it, and the search stops after 25 of them with
    the advice to give a start. A start from a stabilising design works: with kp = 3, ki = 0.1
    the closed loop's characteristic polynomial s^3 + 1.5 s^2 + (kp - 1) s + ki is Hurwitz
    (Routh: 1.5 (kp - 1) = 3 > ki), and the tuner keeps it stable while raising ki."""
    from drivetrain_ctrl.design.robust import InfeasibleSpecError

    P = 1 / ((s - 0.5) * (s + 2))
    with pytest.raises(InfeasibleSpecError, match="needs start=\\(kp, ki\\) from a stabilising"):
        robust_pi(P, ms=2.0)
    r = robust_pi(P, ms=2.0, start=(3.0, 0.1))
    assert r.start_source == "given" and r.ki > 0.1 and r.stable is True
    cl = control.feedback(r.controller * P, 1)
    assert np.all(np.real(control.poles(cl)) < 0)
