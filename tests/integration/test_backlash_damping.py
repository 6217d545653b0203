"""Contact-only damping of a backlash (issue 19, item 9): ``Coupling.damper_in_gap`` and the
drivetrain's ``gearbox.backlash_damping``.

Two inertias ``J1``, ``J2`` joined by a spring ``k`` with half gap ``g`` and a damper ``d``,
nothing else, started in the middle of the gap with relative speed ``w0``
(``mu = 1/J1 + 1/J2``):

* damper in the gap too (the default): ``w' = -d mu w``, so ``w = w0 exp(-d mu t)`` and the
  damper dissipates ``J_red w0^2 (1 - exp(-2 d mu t)) / 2`` (``J_red = 1/mu``), momentum kept;
* damper only in contact: the speeds are constant in the gap (``q = w0 t``, contact at
  ``g / w0``); in contact ``e = q - g`` obeys ``e'' + d mu e' + k mu e = 0``, so
  ``e = w0 exp(-a t) sin(wd t) / wd`` (``a = d mu / 2``, ``wd = sqrt(k mu - a^2)``): the contact
  ends at ``pi / wd`` with the relative speed ``-w0 exp(-a pi / wd)``, and the speeds are
  constant again.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl import linear as L
from drivetrain_ctrl.core.validate import ParameterError
from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Spring
from drivetrain_ctrl.plant.drivetrain import Drivetrain, full_chain, reduced_chain, reduced_figures
from drivetrain_ctrl.plant.model import Mode, Model
from drivetrain_ctrl.plant.params import default_params, field_info, load_params
from drivetrain_ctrl.scenarios.scenario import builtin_scenarios
from drivetrain_ctrl.sim.metrics import state_accelerations
from drivetrain_ctrl.sim.simulator import SimulationOptions, SimulationResult, simulate

J1, J2, K_SPRING, D, W0 = 0.5, 2.0, 100.0, 3.0, 2.0
MU = 1.0 / J1 + 1.0 / J2
TIGHT = SimulationOptions(rtol=1e-11, atol=1e-12)


def two_body(gap: float, damper_in_gap: bool) -> Model:
    spring = Spring.linear(K_SPRING, backlash=gap, name="k")
    coupling = Coupling("lash", spring=spring, damper=D, damper_in_gap=damper_in_gap)
    return Model(Chain((Body("b1", J1), Body("b2", J2)), (coupling,)))


def start(m: Model) -> np.ndarray:
    x0 = np.zeros(m.nx)
    x0[0] = W0  # body 1 turns, body 2 at rest, mid-gap (q = 0)
    return x0


def damper_energy(res: SimulationResult, coupling: str) -> np.ndarray:
    return res.dissipated[:, res.model.power_names().index(f"{coupling}.damper")]


# ------------------------------------------------------------------------------------------------
# (a) two inertias: hand solutions
# ------------------------------------------------------------------------------------------------


def test_damper_in_the_gap_decays_the_relative_speed_exponentially() -> None:
    """Default: in a gap never left (q_inf = w0 / (d mu) < g) the damper alone acts."""
    gap = 0.5
    assert W0 / (D * MU) < gap
    m = two_body(gap, True)
    res = simulate(m, start(m), {}, t_end=0.5, options=TIGHT)
    assert res.status == "ok" and res.events == ()
    assert set(res.mode_series("lash")) == {"gap"}
    t = res.t
    w = res.x[:, 0] - res.x[:, 1]
    np.testing.assert_allclose(w, W0 * np.exp(-D * MU * t), rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(J1 * res.x[:, 0] + J2 * res.x[:, 1], J1 * W0, rtol=1e-12)
    q = res.state("q_lash")
    np.testing.assert_allclose(q, W0 * (1.0 - np.exp(-D * MU * t)) / (D * MU), rtol=1e-8)
    e_d = 0.5 * W0**2 / MU * (1.0 - np.exp(-2.0 * D * MU * t))
    np.testing.assert_allclose(damper_energy(res, "lash"), e_d, rtol=1e-8, atol=1e-14)


def test_contact_only_damper_is_off_in_the_gap_and_damps_the_contact() -> None:
    gap = 0.1
    m = two_body(gap, False)
    a = 0.5 * D * MU
    wd = math.sqrt(K_SPRING * MU - a * a)
    t_in = gap / W0
    t_out = t_in + math.pi / wd
    w_out = -W0 * math.exp(-a * math.pi / wd)
    t_end = 0.4
    assert t_out + 2.0 * gap / abs(w_out) > t_end  # back in the gap, not across it
    res = simulate(m, start(m), {}, t_end=t_end, options=TIGHT)
    assert res.status == "ok"
    got = [(e.element, e.from_mode, e.to_mode) for e in res.events]
    assert got == [("lash", "gap", "contact+"), ("lash", "contact+", "gap")]
    assert res.events[0].t == pytest.approx(t_in, abs=1e-12)
    assert res.events[1].t == pytest.approx(t_out, abs=1e-9)

    E_d = damper_energy(res, "lash")
    mode = res.mode_series("lash")
    first = res.t <= t_in  # in the gap before the contact: nothing acts
    np.testing.assert_array_equal(res.x[first, 0], W0)
    np.testing.assert_array_equal(res.x[first, 1], 0.0)
    np.testing.assert_array_equal(E_d[res.t <= t_in], 0.0)
    # every step taken in the gap adds nothing to the damper's energy; in contact it does
    steps = np.diff(E_d)
    in_gap = np.array([mo == "gap" for mo in mode[:-1]])
    assert np.all(steps[in_gap] == 0.0)
    assert steps[~in_gap].sum() > 0.0
    # the contact as a damped oscillator, and the speeds constant again after it
    after = res.t >= t_out
    w = res.x[:, 0] - res.x[:, 1]
    np.testing.assert_allclose(w[after], w_out, rtol=1e-8)
    np.testing.assert_allclose(J1 * res.x[:, 0] + J2 * res.x[:, 1], J1 * W0, rtol=1e-12)
    contact = (res.t > t_in) & (res.t < t_out)
    tc = res.t[contact] - t_in
    e = W0 * np.exp(-a * tc) * np.sin(wd * tc) / wd
    np.testing.assert_allclose(res.state("q_lash")[contact] - gap, e, rtol=0, atol=1e-10)
    # the damper took exactly the kinetic energy of the relative motion that was lost
    lost = 0.5 / MU * (W0**2 - w_out**2)
    assert E_d[-1] == pytest.approx(lost, rel=1e-8)


def test_whole_run_torques_and_accelerations_honour_contact_only_damping() -> None:
    """The per-sample physics over a run (sim.series, behind ``res.coupling_torques`` and
    ``state_accelerations``) agrees with the kernels row by row: no damper torque in the gap."""
    m = two_body(0.1, False)
    res = simulate(m, start(m), {}, t_end=1.0, options=TIGHT)
    T = res.coupling_torques()[:, 0]
    right, _ = state_accelerations(res)
    in_gap = np.array([mo == "gap" for mo in res.mode_series("lash")])
    assert in_gap.any() and (~in_gap).any()
    assert np.all(T[in_gap] == 0.0) and np.all(right[in_gap, :2] == 0.0)
    u = np.zeros(0)
    for k in range(res.t.shape[0]):
        mode = Mode(tuple(res.fm[k]), tuple(res.reg[k]))
        reg = np.array(mode.reg, dtype=np.int64)
        _, Lam = K.mode_matrices(m.data, np.zeros(0, dtype=np.int64))
        Tk = K.coupling_torques(m.data, res.x[k], u, np.zeros(0, dtype=np.int64), reg, Lam)
        assert T[k] == pytest.approx(Tk[0], rel=1e-13, abs=1e-13)
        np.testing.assert_allclose(right[k], m.rhs(res.x[k], u, mode), rtol=1e-13, atol=1e-13)


# ------------------------------------------------------------------------------------------------
# (b) energy balance
# ------------------------------------------------------------------------------------------------


def test_contact_only_energy_residual() -> None:
    m = two_body(0.1, False)
    res = simulate(m, start(m), {}, t_end=1.5, options=TIGHT)
    assert len(res.events) >= 4  # several contacts and gap crossings
    assert res.energy_residual_rel < 1e-9
    # the powers of the model at every sample: none from the damper in the gap
    for k in range(0, res.t.shape[0], 7):
        mode = Mode(tuple(res.fm[k]), tuple(res.reg[k]))
        _, pd = m.powers(res.x[k], res.u[k], mode)
        w = res.x[k, 0] - res.x[k, 1]
        in_gap = m.mode_names(mode)["lash"] == "gap"
        assert pd["lash.damper"] == (0.0 if in_gap else D * w * w)


# ------------------------------------------------------------------------------------------------
# (c) the drivetrain option reaches the equations
# ------------------------------------------------------------------------------------------------

CONTACT = {"gearbox.backlash_damping": "contact"}


@functools.cache
def tip_in(kind: str, contact: bool) -> SimulationResult:
    p = default_params().replace(**CONTACT) if contact else default_params()
    sc = builtin_scenarios()["tip-in"]
    dt = sc.drivetrain(p, kind=kind)
    return simulate(dt.model, sc.initial_state(dt), sc.input_signals(), t_end=sc.t_end)


@pytest.mark.parametrize("kind", ["full", "reduced"])
def test_tip_in_with_contact_only_damping(kind: str) -> None:
    ref, res = tip_in(kind, False), tip_in(kind, True)
    for r in (ref, res):
        assert r.status == "ok" and r.stats["inconsistent_decisions"] == 0
        assert r.energy_residual_rel <= 1e-6
    # a parameter that changes nothing is a bug: the gap crossing differs
    gap_ref = [e.t for e in ref.events if e.element == "backlash"]
    gap_res = [e.t for e in res.events if e.element == "backlash"]
    assert gap_ref and gap_res and abs(gap_ref[0] - gap_res[0]) < 1e-9  # the gap opens alike
    assert abs(gap_ref[1] - gap_res[1]) > 1e-4  # and closes at another time
    assert np.max(np.abs(ref.x[-1] - res.x[-1])) > 1e-3
    # no damper power in the gap phases (every step that starts in the gap adds nothing)
    for r, off in ((res, True), (ref, False)):
        E_d = damper_energy(r, "backlash")
        in_gap = np.array([mo == "gap" for mo in r.mode_series("backlash")[:-1]])
        assert in_gap.sum() > 10
        steps = np.diff(E_d)[in_gap]
        assert np.all(steps == 0.0) if off else steps.sum() > 0.0


def test_the_option_sets_the_backlash_couplings() -> None:
    p = default_params()
    assert p.gearbox.backlash_damping == "always"
    q = p.replace(**CONTACT)
    for build in (full_chain, reduced_chain):
        by_name = {c.name: c for c in build(p, gear=2).couplings}
        assert by_name["backlash"].damper_in_gap
        by_name = {c.name: c for c in build(q, gear=2).couplings}
        assert not by_name["backlash"].damper_in_gap
        # only the backlash: the other dampers have no gap
        assert all(c.damper_in_gap for n, c in by_name.items() if n != "backlash")
    # no backlash: the two choices are the same model
    z = q.replace(**{"gearbox.g34_wheel": 0.0})
    for kind in ("full", "reduced"):
        a = Drivetrain(z, kind=kind).model.data
        b = Drivetrain(p.replace(**{"gearbox.g34_wheel": 0.0}), kind=kind).model.data
        for fa, fb in zip(a, b, strict=True):
            np.testing.assert_array_equal(fa, fb)


# ------------------------------------------------------------------------------------------------
# (d) linearisation: gap mode vs contact mode
# ------------------------------------------------------------------------------------------------


def _mode_at(m: Model, q: float) -> tuple[np.ndarray, Mode]:
    x = start(m)
    x[m.state_index("q_lash")] = q
    return x, m.mode_from_state(x, np.zeros(0), {})


@pytest.mark.parametrize("in_gap", [True, False])
def test_jacobian_of_a_gap_mode_has_no_damping_with_contact_only(in_gap: bool) -> None:
    m = two_body(0.1, in_gap)
    xg, gap = _mode_at(m, 0.0)
    xc, contact = _mode_at(m, 0.15)
    assert m.mode_names(gap)["lash"] == "gap" and m.mode_names(contact)["lash"] == "contact+"
    u = np.zeros(0)
    Jg, _ = m.jacobian(xg, u, gap)
    Jc, _ = m.jacobian(xc, u, contact)
    damping = np.array([[-D / J1, D / J1], [D / J2, -D / J2]])
    np.testing.assert_allclose(Jc[:2, :2], damping, rtol=1e-15)  # in contact: always damped
    np.testing.assert_allclose(Jc[:2, 2], [-K_SPRING / J1, K_SPRING / J2], rtol=1e-15)
    np.testing.assert_allclose(Jg[:2, :2], damping if in_gap else 0.0, rtol=1e-15, atol=0.0)
    np.testing.assert_array_equal(Jg[:2, 2], 0.0)  # no spring in the gap
    # the POG form's A (the linear part) and the kernels' damping coefficient agree
    A = m.pog_form(gap, xg, u).A
    np.testing.assert_allclose(A[:2, :2], np.diag([J1, J2]) @ Jg[:2, :2], rtol=1e-15, atol=0.0)
    reg = np.array(gap.reg, dtype=np.int64)
    assert K.damper_coefficient(m.data, 0, reg) == (D if in_gap else 0.0)
    # coupling torque in the gap: the damper's or none
    _, Lam = K.mode_matrices(m.data, np.zeros(0, dtype=np.int64))
    T = K.coupling_torques(m.data, xg, u, np.zeros(0, dtype=np.int64), reg, Lam)
    assert T[0] == (D * W0 if in_gap else 0.0)


def test_drivetrain_jacobian_in_the_gap() -> None:
    """Full model, gap mode: with contact-only damping the primary shaft does not see the
    secondary shaft at all (the two speed columns are decoupled)."""
    for contact in (False, True):
        p = default_params().replace(**CONTACT) if contact else default_params()
        dt = Drivetrain(p, gear=1)
        m = dt.model
        x = dt.rigid_state(omega_engine=100.0, v_vehicle=5.0)  # zero torque: mid-gap
        u = m.inputs(throttle=0.0, pedal=0.03, brake=0.0)
        mode, x = m.decide(x, u)
        assert m.mode_names(mode)["backlash"] == "gap"
        J, _ = m.jacobian(x, u, mode)
        ip, isec = m.state_index("omega_primary"), m.state_index("omega_secondary")
        assert bool(J[isec, ip] != 0.0) == (not contact)
        if not contact:
            assert J[isec, ip] == pytest.approx(p.gearbox.tau_r(1) * p.gearbox.b34 / p.gearbox.J4)


def test_judder_threshold_takes_the_shaft_damping_in_contact() -> None:
    """Reduced model, slip point in contact: b_t is the lumped damping with either option."""
    for p in (default_params(), default_params().replace(**CONTACT)):
        dt = Drivetrain(p, kind="reduced")
        op = L.slip_operating_point(
            dt, omega_engine=170.0, omega_driven=80.0, x_c=0.0725, throttle=0.5
        )
        assert op.model.mode_names(op.mode)["backlash"] == "contact+"
        assert L.judder_threshold(op).b_t == reduced_figures(p).b_t


# ------------------------------------------------------------------------------------------------
# (e) bad input
# ------------------------------------------------------------------------------------------------


def test_coupling_contact_only_needs_a_backlash() -> None:
    with pytest.raises(ValueError, match=r"lash\.damper_in_gap = False.*no spring"):
        Coupling("lash", damper=1.0, damper_in_gap=False)
    with pytest.raises(ValueError, match=r"lash\.damper_in_gap = False.*without backlash"):
        Coupling("lash", spring=Spring.linear(10.0), damper=1.0, damper_in_gap=False)
    with pytest.raises(TypeError, match=r"lash\.damper_in_gap = 0: must be a bool"):
        Coupling("lash", spring=Spring.linear(10.0, backlash=0.1), damper_in_gap=0)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"lash\.damper_in_gap = 'no'"):
        Coupling("lash", spring=Spring.linear(10.0, backlash=0.1), damper_in_gap="no")  # type: ignore[arg-type]


@pytest.mark.parametrize("value", ["sometimes", "Contact", "", 1, True, None])
def test_bad_backlash_damping_names_the_field_and_the_value(value: object) -> None:
    with pytest.raises(ParameterError, match=r"gearbox\.backlash_damping = .*'always', 'contact'"):
        default_params().replace(**{"gearbox.backlash_damping": value})


def test_backlash_damping_in_a_file(tmp_path) -> None:
    info = field_info("gearbox.backlash_damping")
    assert info["kind"] == "choice" and info["choices"] == ("always", "contact")
    assert info["optional"] and info["default"] == "always"
    good = tmp_path / "contact.toml"
    good.write_text(
        'base = "passenger-car"\n[meta]\nname = "contact"\n[gearbox]\nbacklash_damping = "contact"\n'
    )
    assert load_params(good).gearbox.backlash_damping == "contact"
    bad = tmp_path / "bad.toml"
    bad.write_text(
        'base = "passenger-car"\n[meta]\nname = "bad"\n[gearbox]\nbacklash_damping = "contcat"\n'
    )
    with pytest.raises(ParameterError, match=r"gearbox\.backlash_damping = 'contcat'.*'contact'"):
        load_params(bad)
