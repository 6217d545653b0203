"""Every figure of merit of :func:`engagement_metrics` checked by value (issue 22 item 1).

Each figure is recomputed here, plainly, from the recorded trajectory of a run on which it is
non-trivial (numpy on the samples, scipy's Butterworth filter for the jerk, the model's
right-hand side for the accelerations, the event list for the modes), following the definition
in :data:`~drivetrain_ctrl.sim.metrics.METRICS` -- never by calling the helper that computes it.
These are also the reference values the compiled metrics of the studies must equal.

Runs: ``engage-ramp`` (open loop: the clutch closes on a ramp, locks once, the backlash chatters)
on both models, and ``paper-start`` in closed loop with the paper's controller on the reduced
model (a reference: the tracking figure).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from scipy import signal

from drivetrain_ctrl.plant.model import Mode
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import load_scenario
from drivetrain_ctrl.sim.metrics import engagement_metrics
from drivetrain_ctrl.sim.run import run_scenario
from drivetrain_ctrl.sim.simulator import SimulationResult

RPM = 30.0 / math.pi  # rad/s -> rpm
KMH = 3.6  # m/s -> km/h
DRIVEN = {"full": "omega_disc", "reduced": "omega_primary"}


@dataclasses.dataclass
class Run:
    res: SimulationResult
    m: dict[str, Any]
    start: float
    reference: Any
    kind: str


@pytest.fixture(scope="module")
def runs() -> dict[str, Run]:
    out = {}
    for name, kind, controller in (
        ("engage-ramp", "reduced", None),
        ("engage-ramp", "full", None),
        ("paper-start", "reduced", "paper"),
    ):
        sc = load_scenario(name)
        dt = sc.drivetrain(default_params(), kind=kind)
        res = run_scenario(sc, dt, controller=controller)
        m = engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)
        out[f"{name}/{kind}"] = Run(res, m, float(sc.start_time), sc.reference, kind)
    return out


# -- plain re-computations ------------------------------------------------------------------------


def lockup(res: SimulationResult, start: float, element: str = "clutch") -> float | None:
    """The first slip -> stuck transition of the clutch at or after ``start`` whose stuck phase
    lasts >= 0.2 s, from the recorded mode series (the event samples are recorded twice)."""
    t = res.t
    stuck = np.array([m == "stuck" for m in res.mode_series(element)])
    for i in range(1, t.shape[0]):
        if stuck[i] and not stuck[i - 1] and t[i] >= start:
            later = np.flatnonzero(~stuck[i:])
            t_end = t[i + later[0]] if later.size else t[-1]
            if t_end - t[i] >= 0.2:
                return float(t[i])
    return None


def windows(r: Run) -> tuple[float, float, float]:
    """(lock-up, end of the engagement window W, end of the slip window)."""
    t_end = float(r.res.t[-1])
    t_lock = lockup(r.res, r.start)
    assert t_lock is not None
    return t_lock, min(t_end, t_lock + 1.0), t_lock


def accelerations(res: SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    """(right, left) limits of the state derivatives at the samples: rhs in the sample's mode and
    in the previous sample's mode (the one the integrator held on the interval before)."""
    model = res.model
    modes = [
        Mode(tuple(int(v) for v in res.fm[i]), tuple(int(v) for v in res.reg[i]))
        for i in range(res.t.shape[0])
    ]
    right = np.array([model.rhs(res.x[i], res.u[i], modes[i]) for i in range(len(modes))])
    left = right.copy()
    for i in range(1, len(modes)):
        if modes[i] != modes[i - 1]:
            left[i] = model.rhs(res.x[i], res.u[i], modes[i - 1])
    return right, left


@pytest.fixture(scope="module")
def acc(runs: dict[str, Run]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {k: accelerations(r.res) for k, r in runs.items()}


# -- the clutch -----------------------------------------------------------------------------------


@pytest.mark.parametrize("key", ["engage-ramp/reduced", "engage-ramp/full", "paper-start/reduced"])
def test_lockup_engagement_time_and_lock_count(runs: dict[str, Run], key: str) -> None:
    r = runs[key]
    t_lock, t_w, _ = windows(r)
    # (the figures are rounded to 9 significant digits)
    assert r.m["lockup_time_s"] == pytest.approx(t_lock, rel=1e-8)
    assert r.m["engagement_time_s"] == pytest.approx(t_lock - r.start, rel=1e-8)
    assert r.m["engagement_time_s"] > 0.5  # a real engagement, not a start that is locked
    # slip -> stuck transitions with their time in W
    t = r.res.t
    stuck = np.array([m == "stuck" for m in r.res.mode_series("clutch")])
    entered = np.flatnonzero(stuck[1:] & ~stuck[:-1]) + 1
    n = int(np.sum((t[entered] >= r.start) & (t[entered] <= t_w)))
    assert n >= 1
    assert r.m["n_lock_events"] == n


@pytest.mark.parametrize("key", ["engage-ramp/reduced", "engage-ramp/full", "paper-start/reduced"])
def test_clutch_energy_is_the_integral_of_torque_times_slip(runs: dict[str, Run], key: str) -> None:
    r = runs[key]
    res = r.res
    t_lock, _, _ = windows(r)
    c = res.model.chain.couplings
    assert c[0].name == "clutch"
    tau = res.coupling_torques()[:, 0]
    ratio = float(res.model.data.ratio[0])
    slip = res.state("omega_engine") - ratio * res.state(DRIVEN[r.kind])
    # trapezoid on an exact dense sampling from the start to lock-up
    ts = np.linspace(r.start, t_lock, 4001)
    d = res.sample(ts)
    tau_d = d.coupling_torques()[:, 0]
    slip_d = d.state("omega_engine") - ratio * d.state(DRIVEN[r.kind])
    energy = float(np.trapezoid(tau_d * slip_d, d.t))
    assert energy > 1000.0
    assert r.m["clutch_energy_J"] == pytest.approx(energy, rel=1e-4)
    # (the recorded samples agree too, less tightly: they are the integrator's steps)
    k = (res.t >= r.start) & (res.t <= t_lock)
    assert float(np.trapezoid((tau * slip)[k], res.t[k])) == pytest.approx(energy, rel=1e-2)


# -- the engine -----------------------------------------------------------------------------------


@pytest.mark.parametrize("key", ["engage-ramp/reduced", "paper-start/reduced"])
def test_engine_speed_extremes_over_the_window(runs: dict[str, Run], key: str) -> None:
    r = runs[key]
    t = r.res.t
    _, t_w, _ = windows(r)
    w = r.res.state("omega_engine")
    inside = (t >= r.start) & (t <= t_w)
    ends = np.interp([r.start, t_w], t, w)
    values = np.concatenate([w[inside], ends]) * RPM
    assert r.m["engine_speed_min_rpm"] == pytest.approx(np.min(values), rel=1e-8)
    assert r.m["engine_speed_max_rpm"] == pytest.approx(np.max(values), rel=1e-8)
    if key.startswith("paper-start"):
        # the highest speed of W is not that of the whole run (the window matters)
        assert np.max(values) < np.max(w) * RPM - 50.0
    assert r.m["engine_stalled"] is False


def test_engine_stall_flag_in_and_out_of_the_window(runs: dict[str, Run]) -> None:
    """The flag is True iff the engine's ground friction is stuck (standstill) at a sample in
    W: the same run with the mode column edited at one sample inside W and one after it."""
    r = runs["paper-start/reduced"]
    res = r.res
    f = [fi.name for fi in res.model.frictions].index("engine")
    _, t_w, _ = windows(r)
    assert np.all(res.fm[:, f] != 0)

    def stalled_at(i: int) -> bool:
        fm = res.fm.copy()
        fm[i, f] = 0
        m = engagement_metrics(dataclasses.replace(res, fm=fm), start=r.start)
        return bool(m["engine_stalled"])

    t = res.t
    i_in = int(np.flatnonzero((t > r.start + 0.1) & (t < t_w))[0])
    i_first = int(np.flatnonzero(t >= r.start)[0])
    i_last = int(np.flatnonzero(t <= t_w)[-1])
    i_after = int(np.flatnonzero(t > t_w + 0.05)[0])
    i_before = int(np.flatnonzero(t < r.start)[-1])
    assert stalled_at(i_in) and stalled_at(i_first) and stalled_at(i_last)
    assert not stalled_at(i_after) and not stalled_at(i_before)


# -- tracking and torque match --------------------------------------------------------------------


def _slip_grid(r: Run) -> np.ndarray:
    """The 1-kHz grid from the start, restricted to the slip window [start + 0.3 s, lock-up]."""
    _, _, t_s = windows(r)
    g = r.start + np.arange(int((r.res.t[-1] - r.start) * 1000.0) + 1) / 1000.0
    g = g[g < r.res.t[-1]]
    return g[(g >= r.start + 0.3) & (g <= t_s)]


def test_tracking_rms_against_the_reference(runs: dict[str, Run]) -> None:
    r = runs["paper-start/reduced"]
    g = _slip_grid(r)
    w = np.interp(g, r.res.t, r.res.state("omega_engine"))
    err = (np.asarray(r.reference(g), dtype=float) - w) * RPM
    rms = math.sqrt(float(np.mean(err**2)))
    assert rms > 1.0
    assert r.m["tracking_rms_rpm"] == pytest.approx(rms, rel=1e-6)
    # the same from the exact samples (the resampling is linear interpolation of the steps)
    e = r.res.sample(g)
    err2 = (np.asarray(r.reference(g), dtype=float) - e.state("omega_engine")) * RPM
    assert r.m["tracking_rms_rpm"] == pytest.approx(math.sqrt(np.mean(err2**2)), rel=1e-2)
    assert runs["engage-ramp/reduced"].m["tracking_rms_rpm"] is None  # open loop


@pytest.mark.parametrize("key", ["engage-ramp/reduced", "engage-ramp/full", "paper-start/reduced"])
def test_torque_match_rms(runs: dict[str, Run], key: str) -> None:
    r = runs[key]
    res = r.res
    g = _slip_grid(r)
    tau = np.interp(g, res.t, res.coupling_torques()[:, 0])
    # the engine torque C_1: the engine's lagged source torque (its lag state times its gain)
    (c1,) = res.source_torques().values()
    d = tau - np.interp(g, res.t, c1)
    rms = math.sqrt(float(np.mean(d**2)))
    assert rms > 1.0
    assert r.m["torque_match_rms_Nm"] == pytest.approx(rms, rel=1e-6)


# -- the vehicle ----------------------------------------------------------------------------------


@pytest.mark.parametrize("key", ["engage-ramp/reduced", "engage-ramp/full"])
def test_vehicle_acceleration_figures(
    runs: dict[str, Run], acc: dict[str, tuple[np.ndarray, np.ndarray]], key: str
) -> None:
    r = runs[key]
    res = r.res
    t = res.t
    iv = res.model.state_names.index("v_vehicle")
    right, left = acc[key][0][:, iv], acc[key][1][:, iv]
    t_lock, t_w, _ = windows(r)
    inside = (t >= r.start) & (t <= t_w)
    peak = max(np.max(np.abs(right[inside])), np.max(np.abs(left[inside & (t > r.start)])))
    assert r.m["vehicle_accel_max_m_s2"] == pytest.approx(peak, rel=1e-8)
    # the vehicle's acceleration is the derivative of its speed (the right-hand side is right)
    ts = np.linspace(r.start + 0.1, t_w - 0.1, 2001)
    v = res.sample(ts).state("v_vehicle")
    fd = np.gradient(v, ts)
    assert np.max(np.abs(fd)) == pytest.approx(peak, rel=0.05)
    # peak-to-peak over [lock-up, lock-up + 1 s], both one-sided limits at the samples
    after = (t >= t_lock) & (t <= t_w)
    i0 = int(np.flatnonzero(after)[0])
    vals = np.concatenate([right[after], left[after & (np.arange(t.shape[0]) > i0)]])
    p2p = float(np.max(vals) - np.min(vals))
    assert p2p > 1.0 and np.min(vals) < 0.0 < np.max(vals)  # max + min would differ
    assert r.m["accel_p2p_after_lock_m_s2"] == pytest.approx(p2p, rel=1e-8)
    # the final speed is the vehicle's (not another state's), in km/h
    assert r.m["final_vehicle_speed_kmh"] == pytest.approx(res.state("v_vehicle")[-1] * KMH)
    assert r.m["final_vehicle_speed_kmh"] > 5.0


def _jerk(t: np.ndarray, a: np.ndarray, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """The filtered jerk on the 1-kHz grid from t[0] and the mask of [t0, t1] on it."""
    fs = 1000.0
    g = t[0] + np.arange(int(round((t[-1] - t[0]) * fs))) / fs
    sos = signal.butter(2, 10.0, fs=fs, output="sos")
    af = signal.sosfiltfilt(sos, np.interp(g, t, a))
    return np.gradient(af, 1.0 / fs), (g >= t0) & (g <= t1)


@pytest.mark.parametrize("key", ["engage-ramp/reduced", "engage-ramp/full"])
def test_jerk_is_the_derivative_of_the_10_hz_filtered_acceleration(
    runs: dict[str, Run], acc: dict[str, tuple[np.ndarray, np.ndarray]], key: str
) -> None:
    """The definition: vehicle acceleration (right limits at the samples) resampled at 1 kHz by
    linear interpolation, 2nd-order Butterworth at 10 Hz forwards and backwards, central
    differences; max |.| and RMS over W."""
    r = runs[key]
    t = r.res.t
    iv = r.res.model.state_names.index("v_vehicle")
    a = acc[key][0][:, iv]
    _, t_w, _ = windows(r)
    jk, win = _jerk(t, a, r.start, t_w)
    jmax = float(np.max(np.abs(jk[win])))
    jrms = math.sqrt(float(np.mean(jk[win] ** 2)))
    assert jmax > 10.0 and 0.0 < jrms < jmax
    assert r.m["jerk_max_m_s3"] == pytest.approx(jmax, rel=1e-6)
    assert r.m["jerk_rms_m_s3"] == pytest.approx(jrms, rel=1e-6)
    # over the whole run the RMS differs: the window matters
    assert math.sqrt(float(np.mean(jk**2))) != pytest.approx(jrms, rel=1e-3)


# -- driveline torques and backlash ---------------------------------------------------------------


@pytest.mark.parametrize("key", ["engage-ramp/reduced", "engage-ramp/full"])
def test_peak_driveline_torques(runs: dict[str, Run], key: str) -> None:
    r = runs[key]
    res = r.res
    t = res.t
    _, t_w, _ = windows(r)
    inside = (t >= r.start) & (t <= t_w)
    names = [c.name for c in res.model.chain.couplings]
    T = res.coupling_torques()
    shaft = float(np.max(np.abs(T[inside, names.index("backlash")])))
    assert shaft > 50.0
    assert r.m["shaft_torque_max_Nm"] == pytest.approx(shaft, rel=1e-8)
    if r.kind == "reduced":
        assert "axle" not in names and r.m["axle_torque_max_Nm"] is None
    else:
        c = names.index("axle")
        axle = float(np.max(np.abs(T[inside, c]))) * float(res.model.data.ratio[c])
        assert axle > shaft  # the wheel frame: after the final drive
        assert r.m["axle_torque_max_Nm"] == pytest.approx(axle, rel=1e-8)


@pytest.mark.parametrize("key", ["engage-ramp/reduced", "engage-ramp/full"])
def test_backlash_impacts_and_crossings(runs: dict[str, Run], key: str) -> None:
    """From the recorded mode series of the backlash: an impact is a sample in W whose mode is a
    contact side while the sample before was in the gap; a crossing is a sample in W where the
    contact side differs from the last contact side seen."""
    r = runs[key]
    t = r.res.t
    _, t_w, _ = windows(r)
    modes = r.res.mode_series("backlash")
    impacts = crossings = 0
    side = ""
    for i, mode in enumerate(modes):
        inside = r.start <= t[i] <= t_w
        if i > 0 and modes[i - 1] == "gap" and mode != "gap" and inside:
            impacts += 1
        if mode != "gap":
            if side and mode != side and inside:
                crossings += 1
            side = mode
    assert impacts >= 2 and crossings >= 1
    assert r.m["n_backlash_impacts"] == impacts
    assert r.m["n_backlash_crossings"] == crossings


def test_filtered_jerk_on_short_signals() -> None:
    """The resampled signal is filtered (forwards and backwards, the pad at most n - 1 samples)
    when it has more than 7 samples, and only differentiated when shorter; written out with
    scipy here on 8 and 7 samples of a ramp plus a step."""
    from drivetrain_ctrl.sim.metrics import filtered_jerk

    sos = signal.butter(2, 10.0, fs=1000.0, output="sos")
    for n in (8, 7):
        t = np.array([0.0, 0.0035, (n - 0.5) / 1000.0])
        acc_in = np.array([0.0, 1.0, 3.0])
        g, af, jk = filtered_jerk(t, acc_in)
        grid = np.arange(n) / 1000.0
        assert np.allclose(g, grid, rtol=0, atol=1e-15)
        raw = np.interp(grid, t, acc_in)
        want = signal.sosfiltfilt(sos, raw, padlen=n - 1) if n > 7 else raw
        np.testing.assert_allclose(af, want, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(jk, np.gradient(want, 1e-3), rtol=1e-12, atol=1e-9)
        assert (n > 7) is not np.allclose(af, raw)


def test_filtered_jerk_on_two_samples_and_near_the_nyquist_frequency() -> None:
    from drivetrain_ctrl.sim.metrics import filtered_jerk

    # two samples in, two grid points out: no filter (fewer than 8), the slope by differences
    g, af, jk = filtered_jerk(np.array([0.0, 0.0015]), np.array([0.0, 3.0]))
    assert g.tolist() == [0.0, 0.001]
    np.testing.assert_allclose(jk, [2000.0, 2000.0], rtol=1e-12)
    # a cut-off just below half the sampling rate is accepted and filters
    t = np.linspace(0.0, 0.1, 11)
    g, af, _ = filtered_jerk(t, np.sin(40.0 * t), cutoff_hz=400.0, fs_hz=1000.0)
    sos = signal.butter(2, 400.0, fs=1000.0, output="sos")
    np.testing.assert_allclose(af, signal.sosfiltfilt(sos, np.interp(g, t, np.sin(40.0 * t))))


def test_the_clutch_name_selects_a_coupling_friction(runs: dict[str, Run]) -> None:
    """``clutch`` names a coupling friction; a ground friction (the engine's) has no lock-up or
    clutch energy, another coupling (the damper's friction) its own stuck phases."""
    r = runs["engage-ramp/full"]
    m = engagement_metrics(r.res, clutch="engine", start=r.start)
    assert m["lockup_time_s"] is None and m["clutch_energy_J"] is None
    assert m["n_lock_events"] is None
    d = engagement_metrics(r.res, clutch="damper_friction", start=r.start)
    t_d = lockup(r.res, r.start, "damper_friction")
    assert t_d != lockup(r.res, r.start)
    if t_d is None:
        assert d["lockup_time_s"] is None
    else:
        assert d["lockup_time_s"] == pytest.approx(t_d, rel=1e-8)


def test_two_sample_records(runs: dict[str, Run]) -> None:
    """The accelerations and the jerk need no more than two samples: the one-sided limits of a
    record of the samples just before and at lock-up, and the figures of a run sampled at its
    two ends only."""
    from drivetrain_ctrl.sim.metrics import state_accelerations

    r = runs["engage-ramp/reduced"]
    res = r.res
    t_lock, _, _ = windows(r)
    i = int(np.flatnonzero((res.t == t_lock) & (res.fm[:, 0] == 0))[0])
    two = dataclasses.replace(
        res, t=res.t[i - 1 : i + 1], x=res.x[i - 1 : i + 1], u=res.u[i - 1 : i + 1],
        fm=res.fm[i - 1 : i + 1], reg=res.reg[i - 1 : i + 1],
    )  # fmt: skip
    right, left = state_accelerations(two)
    before = Mode(tuple(int(v) for v in res.fm[i - 1]), tuple(int(v) for v in res.reg[i - 1]))
    np.testing.assert_allclose(left[1], res.model.rhs(res.x[i], res.u[i], before), rtol=1e-9)
    assert not np.allclose(left[1], right[1])
    ends = res.sample([0.0, 2.0])
    assert ends.t.shape[0] == 2
    m = engagement_metrics(ends, start=0.0)
    iv = res.model.state_names.index("v_vehicle")
    a = np.array([res.model.rhs(ends.x[k], ends.u[k], Mode(
        tuple(int(v) for v in ends.fm[k]), tuple(int(v) for v in ends.reg[k])))[iv]
        for k in range(2)])  # fmt: skip
    jk, win = _jerk(ends.t, a, 0.0, 2.0)
    assert m["jerk_max_m_s3"] == pytest.approx(float(np.max(np.abs(jk[win]))), rel=1e-6)


def test_the_run_keys_name_the_drivetrain(runs: dict[str, Run]) -> None:
    for key, r in runs.items():
        assert r.m["model"] == r.kind and r.m["gear"] == 1, key
        assert r.m["start_s"] == r.start and r.m["status"] == "ok"
    from drivetrain_ctrl.sim.metrics import filtered_jerk

    t = np.linspace(0.0, 2.0, 201)
    g, af, _ = filtered_jerk(t, np.sin(3.0 * t), cutoff_hz=0.5)  # a cut-off below 1 Hz
    sos = signal.butter(2, 0.5, fs=1000.0, output="sos")
    np.testing.assert_allclose(af, signal.sosfiltfilt(sos, np.interp(g, t, np.sin(3.0 * t))))


def test_jerk_difference_quotients_on_uneven_intervals() -> None:
    """(left[k+1] - right[k]) / (t[k+1] - t[k]) written out, on intervals of 0.5 s and 1.5 s
    (a zero-length interval skipped)."""
    from drivetrain_ctrl.sim.metrics import jerk

    t = np.array([0.0, 0.5, 0.5, 2.0])
    right = np.array([1.0, 2.0, 4.0, 0.0])
    left = np.array([1.0, 3.0, 5.0, 7.0])
    assert jerk(t, right, left).tolist() == [(3.0 - 1.0) / 0.5, (7.0 - 4.0) / 1.5]


def test_the_notes_say_whether_the_clutch_locked_up(runs: dict[str, Run]) -> None:
    for r in runs.values():
        assert not any("did not lock up" in n for n in r.m["notes"])
    r = runs["engage-ramp/reduced"]
    t_lock = lockup(r.res, r.start)
    assert t_lock is not None
    sc = load_scenario("engage-ramp")
    dt = sc.drivetrain(default_params(), kind="reduced")
    short = run_scenario(sc, dt, t_end=0.5 * (r.start + t_lock))  # ends before lock-up
    m = engagement_metrics(short, dt, start=sc.start_time)
    assert m["lockup_time_s"] is None
    assert any(n.startswith("the clutch did not lock up") for n in m["notes"])


# -- the vehicle's position ---------------------------------------------------------------------------


def test_rollback_is_the_largest_backward_displacement() -> None:
    """hill-start (12 %) under law (6) on the reduced model, once with its hill-hold brake and
    once with the brake left off: ``rollback_m`` is ``x(t0) - min x`` of the recorded vehicle
    position; without the brake the car rolls back decimetres, with it less than the 5 cm hill-start limit; on
    the flat engage-ramp start the car never moves backwards (round-off, not None)."""
    from drivetrain_ctrl.core.signals import constant

    p = default_params()
    sc = load_scenario("hill-start", params=p)
    dt = sc.drivetrain(p, kind="reduced")
    no_brake = dataclasses.replace(
        sc, inputs=tuple((n, constant(0.0) if n == "brake" else s) for n, s in sc.inputs)
    )
    found = {}
    for label, scen in (("brake", sc), ("no brake", no_brake)):
        res = run_scenario(scen, dt, controller="paper")
        m = engagement_metrics(res, dt, start=scen.start_time, reference=scen.reference)
        x = res.x[:, res.model.state_names.index("pos_vehicle")]
        plain = x[0] - x.min()
        assert plain >= 0.0
        assert m["rollback_m"] == pytest.approx(plain, rel=1e-8, abs=1e-15), label  # 9 digits
        found[label] = m["rollback_m"]
    assert found["no brake"] > 0.05 > found["brake"]
    flat = load_scenario("engage-ramp")
    dtf = flat.drivetrain(p, kind="full")
    mf = engagement_metrics(run_scenario(flat, dtf), dtf, start=flat.start_time)
    assert mf["rollback_m"] is not None and 0.0 <= mf["rollback_m"] < 1e-12  # round-off


def test_a_single_contact_sample_on_each_side_is_one_crossing(runs: dict[str, Run]) -> None:
    """The backlash's region column edited to the gap everywhere except one sample on each
    contact side inside W: one crossing (the new side reached at the second sample)."""
    r = runs["engage-ramp/reduced"]
    res = r.res
    k = next(i for i, ti in enumerate(res.model.tables) if ti.region_names is not None)
    names = list(res.model.tables[k].region_names)
    plus = next(i for i, n in enumerate(names) if n.endswith("+"))
    minus = next(i for i, n in enumerate(names) if n.endswith("-"))
    gap = next(i for i, n in enumerate(names) if not n.endswith(("+", "-")))
    reg = res.reg.copy()
    reg[:, k] = gap
    t = res.t
    i1 = int(np.flatnonzero(t > r.start + 0.1)[0])
    i2 = int(np.flatnonzero(t > r.start + 0.2)[0])
    reg[i1, k] = minus
    reg[i2, k] = plus
    m = engagement_metrics(dataclasses.replace(res, reg=reg), start=r.start)
    assert m["n_backlash_crossings"] == 1
    reg[i2, k] = minus  # both samples on one side: no crossing
    m = engagement_metrics(dataclasses.replace(res, reg=reg), start=r.start)
    assert m["n_backlash_crossings"] == 0


def test_notes_name_a_stall_and_inconsistent_decisions(runs: dict[str, Run]) -> None:
    """The stall note appears iff the engine stalled in W; the decisions note iff the run's
    statistics count inconsistent decisions (a result without the count has none)."""
    r = runs["paper-start/reduced"]
    res = r.res
    assert not any("stalled" in n for n in r.m["notes"])
    f = [fi.name for fi in res.model.frictions].index("engine")
    fm = res.fm.copy()
    fm[int(np.flatnonzero(res.t > r.start + 0.1)[0]), f] = 0
    m = engagement_metrics(dataclasses.replace(res, fm=fm), start=r.start)
    assert m["engine_stalled"] is True
    assert any("engine stalled" in n for n in m["notes"])

    no_count = {k: v for k, v in res.stats.items() if k != "inconsistent_decisions"}
    m = engagement_metrics(dataclasses.replace(res, stats=no_count), start=r.start)
    assert m["inconsistent_decisions"] == 0
    assert not any("mode decision" in n for n in m["notes"])
    m = engagement_metrics(
        dataclasses.replace(res, stats={**res.stats, "inconsistent_decisions": 3}), start=r.start
    )
    assert m["inconsistent_decisions"] == 3
    assert any(n.startswith("3 mode decision(s)") for n in m["notes"])
