"""Value tests of design/clutch.py (issue 22 item 4: mutation score of the design modules): the
trajectory instants of a clutch plant set, on a hand-made mode series and on paper-start."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from drivetrain_ctrl.design.clutch import _slip_instants, clutch_plant_set


def _fake_run(modes: list[str]) -> SimpleNamespace:
    """A recorded run with samples at t = 0, 1, 2, ... s and the clutch's mode series."""
    t = np.arange(len(modes), dtype=float)
    return SimpleNamespace(t=t, mode_series=lambda body: np.array(modes, dtype=object))


def test_slip_instants_split_the_longest_slip_phase_into_equal_parts() -> None:
    """Slip phases [1, 2] and [4, 6] (the last one runs to the end of the run): the longer one,
    [4, 6], in two equal parts has its middles at 4.5 and 5.5 s; from start = 5 s on only [5, 6]
    is left (4 s slips before the start): middle 5.5 s."""
    run = _fake_run(["stuck", "slip+", "slip+", "stuck", "slip-", "slip-", "slip-"])
    assert _slip_instants(run, 0.0, 2) == pytest.approx([4.5, 5.5], abs=1e-15)
    assert _slip_instants(run, 5.0, 1) == pytest.approx([5.5], abs=1e-15)
    # a lone slipping sample is a phase of length 0
    assert _slip_instants(_fake_run(["stuck", "slip+", "stuck"]), 0.0, 3) == [1.0, 1.0, 1.0]
    with pytest.raises(ValueError, match="no slip phase after the controller's start"):
        _slip_instants(run, 6.5, 1)


def test_one_trajectory_instant_is_the_middle_of_the_slip_phase() -> None:
    """times=1 is a valid count (>= 1): the middle of the slip phase, which is the mean of the
    two instants of times=2 (a + (b - a)/4 and a + 3 (b - a)/4)."""
    one = clutch_plant_set(times=1)
    two = clutch_plant_set(times=2)
    assert len(one) == 1
    t1 = one.points[0]["t"]
    t2 = [pt["t"] for pt in two.points]
    assert t1 == pytest.approx(0.5 * (t2[0] + t2[1]), rel=1e-12)
    with pytest.raises(ValueError, match=r"times = 0: must be >= 1"):
        clutch_plant_set(times=0)


def test_latin_hypercube_takes_each_explicit_value_once_per_stratum() -> None:
    """A Latin hypercube of n samples has one sample in each of the n strata [k/n, (k+1)/n) of
    every dimension: with n equal to the number of explicit values each value is taken exactly
    once; an interval dimension gets one value in each n-th of [lo, hi]."""
    from drivetrain_ctrl.design.clutch import _box_points, _Dim

    vals = (1.0, 2.0, 3.0, 4.0)
    dims = [_Dim("a", vals, True), _Dim("b", (10.0, 20.0), False)]
    pts = _box_points(dims, 4, 7, include_nominal=False)
    assert [label for label, _ in pts] == ["sample 0", "sample 1", "sample 2", "sample 3"]
    assert sorted(v["a"] for _, v in pts) == list(vals)
    b = sorted(v["b"] for _, v in pts)
    assert [int((x - 10.0) / 2.5) for x in b] == [0, 1, 2, 3]
    # with the nominal point first (no values: the base car's)
    with_nominal = _box_points(dims, 4, 7, include_nominal=True)
    assert len(with_nominal) == 5 and with_nominal[1:] == pts
