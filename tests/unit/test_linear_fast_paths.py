"""The fast paths behind a study row's paired linear figures (issue 23 item 6) against the
computations they replace: the disk margin from one vectorised frequency response against
python-control's ``disk_margins``; the judder search on the affine state matrix against
re-linearising at every friction slope; the numpy closed loop against python-control's
interconnection; ``clutch_loop_gain`` against ``clutch_loop``; the cached controller stability
check against a fresh one."""

from __future__ import annotations

import dataclasses
import math
import warnings

import control
import numpy as np
import pytest

from drivetrain_ctrl import linear as L
from drivetrain_ctrl.control import laws
from drivetrain_ctrl.control.laws import (
    ControllerSpec,
    UnstableLoopWarning,
    law6_controller,
    load_controller,
    pi_controller,
)
from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.linear import clutch as LC
from drivetrain_ctrl.linear.margins import _auto_grid, _disk_margin, _freq, loop_margins
from drivetrain_ctrl.plant.drivetrain import full_model, reduced_model
from drivetrain_ctrl.plant.params import default_params

P = default_params()
XC = 0.0725  # inside a pedal-map piece (as tests/unit/test_linear.py)


def _slip(kind: str):
    mk = reduced_model if kind == "reduced" else full_model
    return L.slip_operating_point(
        mk(P), omega_engine=170.0, omega_driven=80.0, x_c=XC, throttle=0.5
    )


def _controllers(kind: str):
    driven = "omega_primary" if kind == "reduced" else "omega_disc"
    ref = sg.constant(170.0)
    return [
        None,
        law6_controller(P, reference=ref, driven_state=driven),
        pi_controller(P, kp=1e-3, ki=5e-3, reference=ref, driven_state=driven),
    ]


# -- disk margin ---------------------------------------------------------------------------------

LOOPS = [
    control.tf([2.0], [1.0, 3.0, 2.0, 0.0]),  # type 1, third order
    control.tf([50.0, 100.0], [1.0, 4.0, 30.0, 0.0]),  # lightly damped
    control.tf([0.1], [1.0, 1.0]),  # small gain: alpha > 2 (python-control's conventions)
    control.tf([0.3], [1.0, -0.5], 0.01),  # sampled
]


@pytest.mark.parametrize("Lsys", LOOPS, ids=["type1", "resonant", "small-gain", "sampled"])
def test_disk_margin_equals_python_control(Lsys) -> None:
    w = _auto_grid(Lsys, n=500)
    Lw = _freq(Lsys, w)
    dm, ddb, ddeg = _disk_margin(1.0 / (1.0 + Lw))
    DM, DGM, DPM = control.disk_margins(Lsys, w, skew=0.0)
    for mine, ref in ((dm, DM), (ddb, DGM), (ddeg, DPM)):
        if math.isinf(ref):
            assert math.isinf(mine)
        else:
            assert mine == pytest.approx(float(ref), rel=1e-9)
    m = loop_margins(Lsys, omega=w.tolist())
    assert m.disk_margin == pytest.approx(float(DM), rel=1e-9)
    if float(DM) < 2.0:  # the disk's phase margin 2 atan(alpha/2)
        assert m.disk_margin_deg == pytest.approx(math.degrees(2 * math.atan(dm / 2)), rel=1e-9)


# -- judder search ---------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_judder_crossing_on_the_affine_matrix_equals_relinearising(kind, monkeypatch) -> None:
    op = _slip(kind)
    for ctrl in _controllers(kind):
        fast = LC.judder_crossing(op, ctrl, rtol=1e-4)
        assert LC._affine_slip_matrix(op, ctrl, 1.0) is not None  # the fast path is taken
        with monkeypatch.context() as mp:
            mp.setattr(LC, "_affine_slip_matrix", lambda *a: None)
            slow = LC.judder_crossing(op, ctrl, rtol=1e-4)
        assert fast.available and slow.available
        # same grid and bisection: the same bracket, to rounding of the eigenvalue problems
        assert fast.mu_slope_crit == pytest.approx(slow.mu_slope_crit, rel=1e-9)
        assert fast.stable_side == pytest.approx(slow.stable_side, rel=1e-9)
        assert fast.unstable_side == pytest.approx(slow.unstable_side, rel=1e-9)
        assert fast.frequency_hz == pytest.approx(slow.frequency_hz, rel=1e-6)
        assert fast.evaluations == slow.evaluations


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_affine_slip_matrix_has_the_slip_mode_poles(kind) -> None:
    op = _slip(kind)
    for ctrl in _controllers(kind):
        aff = LC._affine_slip_matrix(op, ctrl, 1.0)
        assert aff is not None
        A0, dA = aff
        for mu in (0.0, -3e-4, -2e-3, -0.5):
            want = np.sort_complex(L.slip_mode_poles(op, ctrl, mu_slope=mu))
            got = np.sort_complex(np.linalg.eigvals(A0 + mu * dA))
            assert got.shape == want.shape
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.max(np.abs(want)))


def test_a_matrix_not_affine_in_the_slope_falls_back(monkeypatch) -> None:
    """A linearisation whose matrix is not affine in mu' is caught by the check (and the
    search then re-linearises at every slope)."""
    op = _slip("reduced")
    ctrl = _controllers("reduced")[1]
    real = LC._slip_plant_arrays

    def bent(op_, mu):
        A, B, C, D, names, outs = real(op_, mu)
        return A + mu * mu * np.eye(A.shape[0]), B, C, D, names, outs

    monkeypatch.setattr(LC, "_slip_plant_arrays", bent)
    assert LC._affine_slip_matrix(op, ctrl, 1.0) is None


# -- the loop gain alone ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_clutch_loop_gain_is_clutch_loops_L(kind) -> None:
    op = _slip(kind)
    ctrl = _controllers(kind)[2]
    loop = LC.clutch_loop(op, ctrl)
    es, Lt = LC.clutch_loop_gain(op, ctrl)
    assert es == loop.engine
    np.testing.assert_array_equal(Lt.num[0][0], loop.L.num[0][0])
    np.testing.assert_array_equal(Lt.den[0][0], loop.L.den[0][0])


# -- controller stability check --------------------------------------------------------------------


def test_stability_check_is_cached_on_what_it_reads(monkeypatch) -> None:
    laws._STABILITY_CACHE.clear()
    calls = []
    real = laws._slip_loop_poles

    def counted(spec, params):
        calls.append(spec.name)
        return real(spec, params)

    monkeypatch.setattr(laws, "_slip_loop_poles", counted)
    spec = load_controller("pi")
    first = spec.check_stability(P)
    again = spec.check_stability(P)
    assert len(calls) == 1 and first == again
    # a parameter the loop does not read: still cached
    heavier = dataclasses.replace(P, vehicle=dataclasses.replace(P.vehicle, M_v=2 * P.vehicle.M_v))
    assert spec.check_stability(heavier) == first and len(calls) == 1
    # one it reads: checked afresh, and equal to an uncached check
    slower = dataclasses.replace(P, actuator=dataclasses.replace(P.actuator, omega_a=40.0))
    got = spec.check_stability(slower)
    assert len(calls) == 2
    laws._STABILITY_CACHE.clear()
    assert spec.check_stability(slower) == got and len(calls) == 3


def test_a_cached_unstable_check_warns_every_time() -> None:
    laws._STABILITY_CACHE.clear()
    bad = ControllerSpec(name="hot", law="paper", k_r=0.02, sample_period_s=0.01, delay_samples=1)
    for _ in range(2):
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            stable, poles = bad.check_stability(P)
        assert not stable and max(abs(p) for p in poles) > 1.0
        assert any(issubclass(r.category, UnstableLoopWarning) for r in rec)
    assert len(laws._STABILITY_CACHE) == 1
