"""Input signals: values, right-continuity, left limits, breakpoints, algebra, serialisation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivetrain_ctrl.core.signals import (
    Signal,
    Sine,
    constant,
    pack_signals,
    ramp,
    sine,
    step,
    table,
)

finite = st.floats(-1e3, 1e3)
times = st.floats(-10.0, 10.0)


def val(s: Signal, t: float) -> float:
    return float(s(t))


# -- elementary signals -------------------------------------------------------------------------


def test_docstring_examples() -> None:
    u = constant(0.2) + step(1.0, 0.3)
    assert val(u, 0.5) == pytest.approx(0.2) and val(u, 1.0) == pytest.approx(0.5)
    assert val(ramp(0.5, 2.5, 0.11, 0.03), 1.5) == pytest.approx(0.07)


@settings(max_examples=100, deadline=None)
@given(t0=times, h=finite, a=finite, dt=st.floats(1e-6, 5.0))
def test_step(t0: float, h: float, a: float, dt: float) -> None:
    s = step(t0, h, initial=a)
    assert val(s, t0 - dt) == a
    assert val(s, t0) == a + h  # right-continuous: the value at the jump is the later one
    assert val(s, t0 + dt) == a + h
    assert s.left_limit(t0) == a
    assert s.left_limit(t0 + dt) == a + h
    assert s.breakpoints == (t0,)


@settings(max_examples=100, deadline=None)
@given(t0=times, dur=st.floats(0.01, 10.0), v0=finite, v1=finite, frac=st.floats(0.0, 1.0))
def test_ramp(t0: float, dur: float, v0: float, v1: float, frac: float) -> None:
    t1 = t0 + dur
    r = ramp(t0, t1, v0, v1)
    assert val(r, t0 - 1.0) == v0
    assert val(r, t1 + 1.0) == v1
    t = t0 + frac * (t1 - t0)
    assert val(r, t) == pytest.approx(
        v0 + (v1 - v0) * (t - t0) / (t1 - t0), abs=1e-9 * (1 + abs(v0) + abs(v1))
    )
    # continuous: the left limit equals the value everywhere
    assert r.left_limit(t) == pytest.approx(val(r, t), abs=1e-9 * (1 + abs(v0) + abs(v1)))
    assert r.breakpoints == (t0, t1)


def test_table_with_a_jump() -> None:
    s = table([0.0, 1.0, 1.0, 2.0], [0.0, 1.0, 3.0, 3.0])
    assert val(s, -1.0) == 0.0
    assert val(s, 0.5) == pytest.approx(0.5)
    assert s.left_limit(1.0) == pytest.approx(1.0)
    assert val(s, 1.0) == 3.0
    assert val(s, 1.5) == 3.0 and val(s, 5.0) == 3.0
    assert s.breakpoints == (0.0, 1.0, 2.0)
    np.testing.assert_allclose(s(np.array([0.25, 1.0, 3.0])), [0.25, 3.0, 3.0])
    # left limit before the first knot is the first value
    assert s.left_limit(-3.0) == 0.0


def test_jump_at_the_last_knot() -> None:
    s = table([0.0, 2.0, 2.0], [1.0, 2.0, -1.0])
    assert s.left_limit(2.0) == pytest.approx(2.0)
    assert val(s, 2.0) == -1.0 and val(s, 7.0) == -1.0


@settings(max_examples=100, deadline=None)
@given(
    amp=st.floats(-5.0, 5.0),
    om=st.floats(0.1, 50.0),
    ph=st.floats(-3.0, 3.0),
    ts=st.floats(0.0, 5.0),
    t=st.floats(-5.0, 10.0),
)
def test_sine(amp: float, om: float, ph: float, ts: float, t: float) -> None:
    s = sine(amp, om, phase=ph, t_start=ts)
    expected = amp * math.sin(om * (t - ts) + ph) if t >= ts else 0.0
    assert val(s, t) == pytest.approx(expected, abs=1e-12)
    # a sine that starts with a non-zero phase jumps at t_start
    assert s.left_limit(ts) == 0.0
    assert val(s, ts) == pytest.approx(amp * math.sin(ph), abs=1e-12)
    assert ts in s.breakpoints


# -- algebra ---------------------------------------------------------------------------------------


signal_parts = st.fixed_dictionaries(
    {
        "c": finite,
        "step": st.tuples(times, finite),
        "ramp": st.tuples(times, st.floats(0.01, 5.0), finite, finite),
        "sine": st.tuples(st.floats(-5, 5), st.floats(0.1, 20.0), st.floats(0.0, 5.0)),
        "k": st.floats(-3.0, 3.0),
    }
)


@settings(max_examples=100, deadline=None)
@given(parts=signal_parts, ts=st.lists(st.floats(-12.0, 15.0), min_size=1, max_size=8))
def test_sum_is_pointwise(parts: dict, ts: list[float]) -> None:
    c = constant(parts["c"])
    s1 = step(*parts["step"])
    t0, dur, v0, v1 = parts["ramp"]
    r = ramp(t0, t0 + dur, v0, v1)
    sn = sine(parts["sine"][0], parts["sine"][1], t_start=parts["sine"][2])
    total = c + s1 + r + sn
    k = parts["k"]
    scaled = k * total - s1
    for t in ts:
        parts_val = val(c, t) + val(s1, t) + val(r, t) + val(sn, t)
        assert val(total, t) == pytest.approx(parts_val, abs=1e-9 * (1 + abs(parts_val)))
        assert val(scaled, t) == pytest.approx(
            k * parts_val - val(s1, t), abs=1e-9 * (1 + abs(k * parts_val) + abs(val(s1, t)))
        )
        left = c.left_limit(t) + s1.left_limit(t) + r.left_limit(t) + sn.left_limit(t)
        assert total.left_limit(t) == pytest.approx(left, abs=1e-9 * (1 + abs(left)))
    assert set(total.breakpoints) == set(c.breakpoints) | set(s1.breakpoints) | set(
        r.breakpoints
    ) | set(sn.breakpoints)
    assert list(total.breakpoints) == sorted(total.breakpoints)


def test_sum_with_scalars_and_negation() -> None:
    s = step(1.0, 2.0)
    assert val(s + 1.0, 0.0) == 1.0 and val(1.0 + s, 2.0) == 3.0
    assert val(s - 0.5, 2.0) == 1.5
    assert val(-s, 2.0) == -2.0
    assert val(s * 3.0, 2.0) == 6.0 and val(3.0 * s, 0.0) == 0.0


# -- serialisation ---------------------------------------------------------------------------------


@settings(max_examples=100, deadline=None)
@given(
    knots=st.lists(st.tuples(st.floats(-5, 5), finite), min_size=1, max_size=6),
    jump=st.booleans(),
    sines=st.lists(
        st.tuples(st.floats(-5, 5), st.floats(0.1, 20), st.floats(-3, 3), st.floats(0, 5)),
        max_size=2,
    ),
)
def test_to_dict_from_dict_round_trip(knots, jump, sines) -> None:
    ts = sorted(t for t, _ in knots)
    if len(set(ts)) != len(ts):
        ts = sorted(set(ts))
    vs = [v for _, v in knots][: len(ts)]
    if jump and len(ts) >= 1:
        ts = ts + [ts[-1]]
        vs = vs + [vs[-1] + 1.0]
    s = Signal(tuple(ts), tuple(vs), tuple(Sine(*p) for p in sines))
    d = s.to_dict()
    assert set(d) == ({"times", "values", "sines"} if sines else {"times", "values"})
    s2 = Signal.from_dict(d)
    assert s2 == s
    for t in (-6.0, 0.0, 1.3, 7.0):
        assert val(s2, t) == val(s, t)


def test_pack_signals() -> None:
    a = step(1.0, 2.0)
    b = sine(1.0, 2.0) + ramp(0.0, 1.0, 0.0, 1.0)
    arr = pack_signals([a, b])
    assert arr.t.shape == (2, 2) and arr.sin.shape == (2, 1, 4)
    assert list(arr.nk) == [2, 2] and list(arr.ns) == [0, 1]
    np.testing.assert_array_equal(arr.t[0], [1.0, 1.0])
    np.testing.assert_array_equal(arr.v[0], [0.0, 2.0])
    np.testing.assert_array_equal(arr.sin[1, 0], [1.0, 2.0, 0.0, 0.0])


# -- bad inputs ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("make", "exc", "field"),
    [
        (lambda: step(float("nan"), 1.0), ValueError, "t_step"),
        (lambda: step(0.0, float("inf")), ValueError, "height"),
        (lambda: step(0.0, 1.0, initial=float("nan")), ValueError, "initial"),
        (lambda: ramp(1.0, 1.0, 0.0, 1.0), ValueError, "t_end"),
        (lambda: ramp(1.0, 0.5, 0.0, 1.0), ValueError, "t_end"),
        (lambda: ramp(0.0, 1.0, float("nan"), 1.0), ValueError, "v_start"),
        (lambda: ramp(0.0, 1.0, 0.0, float("inf")), ValueError, "v_end"),
        (lambda: sine(1.0, float("nan")), ValueError, "omega"),
        (lambda: sine(float("inf"), 1.0), ValueError, "amplitude"),
        (lambda: sine(1.0, 1.0, phase=float("nan")), ValueError, "phase"),
        (lambda: sine(1.0, 1.0, t_start=float("inf")), ValueError, "t_start"),
        (lambda: constant("1.0"), TypeError, "value"),
        (lambda: constant(True), TypeError, "value"),
        (lambda: constant(float("nan")), ValueError, "value"),
        (lambda: table([0.0, 2.0, 1.0], [0.0, 1.0, 2.0]), ValueError, "times"),
        (lambda: table([0.0, 1.0, 1.0, 1.0], [0.0, 1.0, 2.0, 3.0]), ValueError, "times"),
        (lambda: table([0.0, float("nan")], [0.0, 1.0]), ValueError, r"times\[1\]"),
        (lambda: table([0.0, 1.0], [0.0, float("inf")]), ValueError, r"values\[1\]"),
        (lambda: table([0.0, 1.0], [0.0]), ValueError, "times and values"),
        (lambda: table([], []), ValueError, "non-empty"),
        (lambda: step(0.0, 1.0) * float("nan"), ValueError, "scale"),
        (lambda: step(0.0, 1.0) + float("inf"), ValueError, "constant"),
    ],
)
def test_bad_inputs_name_the_field(make, exc, field: str) -> None:
    with pytest.raises(exc, match=field):
        make()


@pytest.mark.parametrize(
    ("d", "field"),
    [
        ({"times": [0.0], "values": [1.0], "extra": 1}, "extra"),
        ({"times": [0.0]}, "values"),
        ({"values": [0.0]}, "times"),
        ({"times": [1.0, 0.0], "values": [0.0, 1.0]}, "times"),
        ({"times": [0.0, float("nan")], "values": [0.0, 1.0]}, r"times\[1\]"),
        ({"times": [0.0], "values": [float("inf")]}, r"values\[0\]"),
        ({"times": [0.0], "values": [0.0], "sines": [{"amplitude": 1.0, "omegaa": 1.0}]}, "omegaa"),
    ],
)
def test_from_dict_bad_inputs_name_the_field(d: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        Signal.from_dict(d, name="pedal")
    with pytest.raises(ValueError, match="pedal"):
        Signal.from_dict(d, name="pedal")


@pytest.mark.parametrize("key", ["amplitude", "omega", "phase", "t_start"])
def test_from_dict_rejects_non_finite_sine(key: str) -> None:
    sn = {"amplitude": 1.0, "omega": 2.0, "phase": 0.0, "t_start": 0.0, key: float("nan")}
    with pytest.raises(ValueError, match=key):
        Signal.from_dict({"times": [0.0], "values": [0.0], "sines": [sn]})


def test_from_dict_missing_sine_key_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="amplitude"):
        Signal.from_dict({"times": [0.0], "values": [0.0], "sines": [{"omega": 1.0}]}, name="pedal")


# ------------------------------------------------------------------------------------------------
# extremes (the simulator's input-range check) and bad input
# ------------------------------------------------------------------------------------------------


def test_extremes_of_the_piecewise_linear_part_are_exact_and_earliest() -> None:
    assert ramp(0.2, 2.2, 0.11, 0.03).extremes(0.0, 3.0) == ((0.03, 2.2), (0.11, 0.0))
    # both sides of a jump count; of equal values the earliest time is given
    s = table([0.0, 1.0, 1.0, 2.0], [0.0, 1.0, 5.0, 0.0])
    assert s.extremes(0.5, 1.5) == ((0.5, 0.5), (5.0, 1.0))
    assert step(0.5, -1.5, initial=0.5).extremes(0.0, 3.0) == ((-1.0, 0.5), (0.5, 0.0))
    # only the window counts
    assert step(2.0, 10.0).extremes(0.0, 1.0) == ((0.0, 0.0), (0.0, 0.0))


@settings(max_examples=30, deadline=None)
@given(a=st.floats(0.0, 2.0), w=st.floats(0.5, 50.0), c=finite, t0=st.floats(0.0, 1.0))
def test_extremes_with_sines_bracket_a_dense_sampling(
    a: float, w: float, c: float, t0: float
) -> None:
    s = constant(c) + ramp(0.3, 0.8, 0.0, 1.0) + sine(a, w, t_start=t0)
    (lo, _), (hi, _) = s.extremes(0.0, 2.0)
    v = np.asarray(s(np.linspace(0.0, 2.0, 20001)))
    tol = 1e-2 * (a + 1.0)  # grid of 40 points a period: within 0.3 % of the amplitude
    assert lo <= v.min() + tol and hi >= v.max() - tol
    # and never beyond what the signal can reach (ramp part within [c, c + 1])
    assert lo >= c - a - 1e-9 and hi <= c + 1.0 + a + 1e-9


@pytest.mark.parametrize(
    ("fn", "exc", "match"),
    [
        (lambda: table(["a"], [0.0]), TypeError, r"table: times\[0\] must be a real number"),
        (lambda: table([0.0], [math.nan]), ValueError, r"table: values\[0\] must be finite"),
        (lambda: table(1.0, 2.0), TypeError, "table: times = 1.0: must be a sequence"),
        (lambda: constant(1.0) - "a", TypeError, "constant must be a real number, got 'a'"),
        (lambda: Signal((0.0,), (1.0,), (1.0,)), TypeError, r"Signal.sines\[0\] = 1.0"),
        (lambda: Signal([0.0], [1.0]), TypeError, r"Signal.times = \[0.0\]: must be a tuple"),
    ],
)
def test_bad_signal_construction_names_the_field(fn: object, exc: type, match: str) -> None:
    with pytest.raises(exc, match=match):
        fn()  # type: ignore[operator]


@pytest.mark.parametrize(
    ("d", "match"),
    [
        (5.0, r"inputs.pedal = 5.0: must be a table with 'times' and 'values'"),
        ("ramp", r"inputs.pedal = 'ramp': must be a table"),
        (
            {"times": [0.0], "values": [1.0], "sines": {"amplitude": 1.0, "omega": 2.0}},
            r"inputs.pedal.sines = .*array of tables.*\[\[inputs.pedal.sines\]\]",
        ),
        ({"times": [0.0], "values": [1.0], "sines": 5}, r"inputs.pedal.sines = 5"),
    ],
)
def test_from_dict_with_wrong_types_names_the_field(d: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Signal.from_dict(d, name="inputs.pedal")  # type: ignore[arg-type]


def test_extremes_checks_its_window() -> None:
    with pytest.raises(ValueError, match="extremes: t0 = 2.0 s must be <= t1 = 1.0 s"):
        constant(1.0).extremes(2.0, 1.0)
    with pytest.raises(ValueError, match="extremes: t1 must be finite"):
        constant(1.0).extremes(0.0, math.inf)
