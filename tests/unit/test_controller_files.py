"""Controller files with a general LTI law (issue 20 item 6): the ``"lti"`` law's coefficients
(transfer function or state space), its anti-windup rule, the ``[design]`` provenance table, the
TOML round trip and pickling; no simulation (the closed-loop runs: tests/integration/
test_controller_lti.py)."""

from __future__ import annotations

import dataclasses
import pickle
import tomllib
from pathlib import Path
from typing import Any

import control
import numpy as np
import pytest

from drivetrain_ctrl.control.laws import (
    MIN_ANTI_WINDUP_TIME_S,
    ControllerError,
    ControllerSpec,
    builtin_controllers,
    controller_from_dict,
    load_controller,
    save_controller,
    spec_from_lti,
)
from drivetrain_ctrl.core.signals import constant
from drivetrain_ctrl.plant.params import default_params

P = default_params()

#: coefficients chosen to stress a text round trip: not short decimals, a negative zero, a
#: subnormal, huge and tiny exponents
AWKWARD = (1.0 / 3.0, -0.0, 5e-324, 1.2345678901234567e-300, 0.1 + 0.2, 7.0e22)


def _bits(values: Any) -> list[str]:
    """Every float of a (nested) tuple/list as its exact hex form (bitwise comparison; -0.0 and
    0.0 differ)."""
    if isinstance(values, list | tuple):
        return [b for v in values for b in _bits(v)]
    return [float(values).hex()]


def _lti_specs() -> list[ControllerSpec]:
    kp, ki = 1.0e-3, 5.0e-3
    return [
        ControllerSpec(
            name="tf-awkward",
            law="lti",
            num=(AWKWARD[0], AWKWARD[5] * 1e-30),
            den=(1.0, AWKWARD[4]),
            x_r0=0.065,
            design={
                "method": "robust-pi",
                "ms": 1.4,
                "plants": 12,
                "converged": True,
                "history": {"ki": [1e-3, 2e-3, 2.5e-3], "note": 'quote " and \\ slash, é'},
                "grid": np.geomspace(0.1, 100.0, 4),  # arrays become lists
                "weight": np.float32(0.5),
                "margins": {"gm_db": float("inf")},
            },
        ),
        ControllerSpec(
            name="ss-awkward",
            law="lti",
            A=np.array([[AWKWARD[1], AWKWARD[2]], [AWKWARD[3], -AWKWARD[0]]]),
            B=[1.0, AWKWARD[4]],
            C=(AWKWARD[0], 0.0),
            D=np.float64(kp),
            sample_period_s=0.01,
            delay_samples=2,
            back_calculation_time_s=0.3,
            rate_limit_m_s=0.4,
        ),
        ControllerSpec(name="static", law="lti", A=[], B=[], C=[], D=3.0e-4),
        ControllerSpec(name="pi-tf", law="lti", num=[kp, ki], den=[1, 0]),  # ints are floats
    ]


@pytest.mark.parametrize("spec", _lti_specs(), ids=lambda s: s.name)
def test_toml_round_trip_is_exact_and_specs_pickle(spec: ControllerSpec, tmp_path: Path) -> None:
    path = spec.to_toml(tmp_path / f"{spec.name}.toml", header="a header line\nand another")
    text = path.read_text(encoding="utf-8")
    assert text.startswith("# a header line\n# and another\n# drivetrain_ctrl controller")
    back = load_controller(path)
    assert back == spec
    for k in ("num", "den", "A", "B", "C", "D"):
        if getattr(spec, k) is not None:
            assert _bits(getattr(back, k)) == _bits(getattr(spec, k)), k
    assert load_controller(save_controller(back, tmp_path / "again.toml")) == spec
    # the file is plain TOML (any reader) holding what to_dict says
    assert tomllib.loads(text) == spec.to_dict()
    # picklable (a study ships specs to worker processes), equal and hashable
    again = pickle.loads(pickle.dumps(spec))
    assert again == spec and hash(again) == hash(spec)
    # the same LTI block after the round trip
    a, b = spec.lti(), back.lti()
    for m in ("A", "B", "C", "D"):
        assert np.array_equal(np.asarray(getattr(a, m)), np.asarray(getattr(b, m)))
    assert a.dt == b.dt


def test_design_table_is_normalised_and_shown_as_given() -> None:
    spec = _lti_specs()[0]
    assert spec.design is not None
    assert spec.design["grid"] == pytest.approx([0.1, 1.0, 10.0, 100.0])
    assert type(spec.design["weight"]) is float and type(spec.design["plants"]) is int
    assert spec.to_dict()["design"]["history"]["ki"] == [1e-3, 2e-3, 2.5e-3]
    # a design table does not change the controller
    bare = dataclasses.replace(spec, design=None)
    assert bare != spec and hash(bare) == hash(spec)


@pytest.mark.parametrize("name", list(builtin_controllers()))
def test_builtin_files_round_trip(name: str, tmp_path: Path) -> None:
    spec = builtin_controllers()[name]
    assert load_controller(spec.to_toml(tmp_path / "c.toml")) == spec


@pytest.mark.parametrize(
    "d,match",
    [
        ({"law": "lti", "nun": [1.0], "den": [1.0]}, r"nun: unknown key; did you mean 'num'\?"),
        ({"law": "lti"}, "needs its coefficients: num and den"),
        ({"law": "lti", "num": [1.0]}, r"den: missing"),
        ({"law": "lti", "A": [[0.0]], "B": [1.0], "C": [1.0]}, r"D: missing"),
        (
            {"law": "lti", "num": [1.0], "den": [1.0], "D": 1.0},
            "give num/den or A, B, C, D, not both",
        ),
        ({"law": "lti", "num": [1.0, 0.0, 0.0], "den": [1.0, 2.0]}, "improper"),
        ({"law": "lti", "num": [1.0], "den": [0.0, 1.0]}, r"den\[0\] = 0\.0"),
        ({"law": "lti", "num": [0.0, 0.0], "den": [1.0, 1.0]}, "does nothing"),
        ({"law": "lti", "num": [1.0, "x"], "den": [1.0, 1.0]}, r"num\[1\] = 'x'"),
        ({"law": "lti", "num": [1.0, float("nan")], "den": [1.0, 1.0]}, r"num\[1\] = nan"),
        ({"law": "lti", "num": 1.0, "den": [1.0]}, r"num = 1\.0: must be a list"),
        ({"law": "lti", "A": [[0.0, 1.0]], "B": [1.0], "C": [1.0], "D": 0.0}, r"A\[0\] = .*square"),
        ({"law": "lti", "A": [[0.0]], "B": [1.0, 2.0], "C": [1.0], "D": 0.0}, r"B = .*needs 1"),
        ({"law": "lti", "A": [[0.0]], "B": [1.0], "C": [1.0], "D": [1.0]}, r"D = \[1\.0\]"),
        ({"law": "lti", "num": [1.0], "den": [1.0], "kp": 1e-3}, "kp/ki are PI gains"),
        ({"law": "lti", "num": [1.0], "den": [1.0], "k_r": 1e-3}, r"k_r = 0\.001: law \(6\)"),
        ({"law": "pi", "kp": 1e-3, "ki": 1e-3, "num": [1.0]}, r"num = \[1\.0\]: coefficients of"),
        ({"law": "paper", "back_calculation_time_s": 0.1}, "law 'paper' has no integrator"),
        (
            {
                "law": "pi",
                "kp": 1e-3,
                "ki": 1e-3,
                "anti_windup": False,
                "back_calculation_time_s": 1.0,
            },
            "anti_windup = false",
        ),
        ({"law": "pi", "kp": 1e-3, "ki": 1e-3, "back_calculation_time_s": -1.0}, "back_calc"),
        ({"law": "paper", "design": 3}, r"design = 3: must be a table"),
        ({"law": "paper", "design": {"a": {"b": None}}}, r"design\.a\.b = None: .*no null"),
        ({"law": "paper", "design": {"x": [1.0, float("nan")]}}, r"design\.x\[1\] = nan"),
    ],
)
def test_bad_lti_files_name_the_field(d: dict[str, Any], match: str) -> None:
    with pytest.raises(ControllerError, match=match):
        controller_from_dict(d)


def test_a_bad_file_names_the_key_and_the_file(tmp_path: Path) -> None:
    f = tmp_path / "bad.toml"
    f.write_text('name = "bad"\nlaw = "lti"\nnum = [1.0]\nden = [1.0]\n[desing]\nx = 1\n')
    with pytest.raises(
        ControllerError, match=r"desing: unknown key; did you mean 'design'\?.*bad\.toml"
    ):
        load_controller(f)
    with pytest.raises(ControllerError, match=r"path = .*\.txt.*must end in \.toml"):
        _lti_specs()[3].to_toml(tmp_path / "c.txt")


# -- the LTI block and its anti-windup rule ------------------------------------------------------


def test_lti_block_is_the_given_transfer_function() -> None:
    kp, ki, kd, tf = 1.0e-3, 5.0e-3, 1.0e-4, 0.01
    C = control.tf([kp], [1]) + control.tf([ki], [1, 0]) + control.tf([kd, 0], [tf, 1])
    w = np.array([0.3, 3.0, 30.0, 300.0])
    for form in ("tf", "ss"):
        spec = spec_from_lti(C, name="pid", form=form)
        assert spec.law == "lti" and spec.sample_period_s is None
        got = spec.lti().frequency_response(w).complex.reshape(-1)
        want = kp + ki / (1j * w) + kd * 1j * w / (tf * 1j * w + 1)
        np.testing.assert_allclose(got, want, rtol=1e-12)
    Cd = control.c2d(C, 0.01, "tustin")
    spec = spec_from_lti(Cd, name="pid-10ms", delay_samples=1)
    assert spec.sample_period_s == 0.01 and spec.lti().dt == 0.01
    np.testing.assert_allclose(
        spec.lti().frequency_response(w).complex.reshape(-1),
        Cd.frequency_response(w).complex.reshape(-1),
        rtol=1e-10,
    )


def test_pi_as_lti_has_the_pi_realisation_and_anti_windup_time() -> None:
    """num/den of a PI give law 'pi''s own realisation (A = 0, B = 1, C = ki, D = kp) and the
    same back-calculation time T_t = kp/ki: the two laws integrate the same state."""
    pi = builtin_controllers()["pi"]
    assert pi.kp is not None and pi.ki is not None
    lti = ControllerSpec(name="pi-lti", law="lti", num=[pi.kp, pi.ki], den=[1.0, 0.0])
    a, b = pi.lti(), lti.lti()
    for m in ("A", "B", "C", "D"):
        assert np.array_equal(np.asarray(getattr(a, m)), np.asarray(getattr(b, m))), m
    assert lti.anti_windup_time_s() == pi.anti_windup_time_s() == pi.kp / pi.ki


def test_anti_windup_rule_of_an_lti_law() -> None:
    """T_t = kp/ki of the integrator's residue ki and the rest kp at s = 0 (z = 1)."""
    kp, ki, kd, tf, ts = 1.0e-3, 5.0e-3, 1.0e-4, 0.01, 0.01
    pid = control.tf([kp], [1]) + control.tf([ki], [1, 0]) + control.tf([kd, 0], [tf, 1])
    for form in ("tf", "ss"):
        assert spec_from_lti(pid, name="p", form=form).anti_windup_time_s() == pytest.approx(
            kp / ki, rel=1e-9
        )
    # Tustin: ki/s -> ki Ts/2 (z + 1)/(z - 1) = ki Ts/(z - 1) + ki Ts/2, so the rest at z = 1 is
    # kp + ki Ts/2 (the derivative term vanishes there)
    tustin = spec_from_lti(control.c2d(pid, ts, "tustin"), name="p", form="ss")
    assert tustin.anti_windup_time_s() == pytest.approx((kp + ki * ts / 2) / ki, rel=1e-9)
    # forward Euler, written as a transfer function in z: kp + ki Ts/(z - 1)
    fe = ControllerSpec(
        name="fe", law="lti", num=[kp, ki * ts - kp], den=[1.0, -1.0], sample_period_s=ts
    )
    assert fe.anti_windup_time_s() == pytest.approx(kp / ki, rel=1e-12)
    # a fast integral action is floored like the PI's
    fast = ControllerSpec(name="f", law="lti", num=[1e-6, 1.0], den=[1.0, 0.0])
    assert fast.anti_windup_time_s() == MIN_ANTI_WINDUP_TIME_S
    # no integrator: nothing winds up; off; explicit value wins
    lead = ControllerSpec(name="lead", law="lti", num=[1e-3, 1e-2], den=[1.0, 50.0])
    assert lead.anti_windup_time_s() is None
    assert dataclasses.replace(fe, anti_windup=False).anti_windup_time_s() is None
    assert dataclasses.replace(fe, back_calculation_time_s=0.7).anti_windup_time_s() == 0.7
    # a slow pole is not an integrator (give the time explicitly for such a controller)
    slow = ControllerSpec(name="slow", law="lti", num=[1e-3, 5e-3], den=[1.0, 1e-4])
    assert slow.anti_windup_time_s() is None
    # two integrators: the rule does not apply; the file must say what to do
    with pytest.raises(ControllerError, match="2 integrators: give back_calculation_time_s"):
        ControllerSpec(name="ii", law="lti", num=[1e-3, 1e-3, 1e-3], den=[1.0, 0.0, 0.0])
    ii = ControllerSpec(
        name="ii", law="lti", num=[1e-3, 1e-3, 1e-3], den=[1.0, 0.0, 0.0], anti_windup=False
    )
    assert ii.anti_windup_time_s() is None


def test_lti_law_builds_a_controller_like_law_6() -> None:
    """Sign switch, offset, saturation, latch, actuator and delay as for law (6) and the PI; the
    LTI block the spec's."""
    pi = builtin_controllers()["pi-10ms"]
    spec = ControllerSpec(
        name="x",
        law="lti",
        A=[[1.0]],
        B=[0.01],
        C=[5e-3],
        D=1e-3,
        sample_period_s=0.01,
        delay_samples=1,
        x_r0=0.07,
    )
    ref = constant(150.0)
    a = pi.build(P, reference=ref, start_time=0.5)
    b = spec.build(P, reference=ref, start_time=0.5)
    same_lti = dataclasses.replace(b, name=a.name, lti=a.lti)  # StateSpace compares by identity
    assert same_lti == a
    for m in ("A", "B", "C", "D"):
        assert np.array_equal(np.asarray(getattr(a.lti, m)), np.asarray(getattr(b.lti, m))), m
    assert a.lti.dt == b.lti.dt


def test_spec_from_lti_checks_its_input() -> None:
    with pytest.raises(ControllerError, match="must be a python-control LTI"):
        spec_from_lti([1.0], name="x")  # type: ignore[arg-type]
    with pytest.raises(ControllerError, match="must be SISO"):
        spec_from_lti(control.ss(np.eye(2), np.eye(2), np.eye(2), np.zeros((2, 2))), name="x")
    with pytest.raises(ControllerError, match="sys.dt = True"):
        spec_from_lti(control.tf([1.0], [1.0, -0.5], True), name="x")
    with pytest.raises(ControllerError, match=r"form = 'zpk'"):
        spec_from_lti(control.tf([1.0], [1.0, 1.0]), name="x", form="zpk")
    with pytest.raises(ControllerError, match=r"rate_limit: unknown key; did you mean"):
        spec_from_lti(control.tf([1.0], [1.0, 1.0]), name="x", rate_limit=0.4)
