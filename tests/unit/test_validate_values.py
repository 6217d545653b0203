"""Value tests of drivetrain_ctrl.core.validate (issue 22 item 4): every check's accept/reject
boundary, the error class it raises and the value it returns, each against a hand-written case.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drivetrain_ctrl.core.validate import (
    ParameterError,
    check_finite,
    check_name,
    check_sequence,
    check_type,
    did_you_mean,
    finite_float,
    is_finite_real,
    is_real,
    positive_float,
    real_number,
    reject_unknown,
    store_knots,
)


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (1, True),
        (-2.5, True),
        (np.int8(3), True),
        (np.float32(0.5), True),
        (float("nan"), True),
        (True, False),
        (np.bool_(False), False),
        ("1.0", False),
        (None, False),
        (1 + 0j, False),
        (np.array(1.0), False),  # a 0-d array is not a scalar for is_real
    ],
)
def test_is_real(value: object, expected: bool) -> None:
    assert is_real(value) is expected


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (0, True),
        (-3.25, True),
        (np.float64(1e300), True),
        (np.array(2.0), True),  # 0-d float array
        (np.array(7), True),  # 0-d int array
        (np.array(np.uint8(4)), True),
        (np.array(float("inf")), False),
        (np.array(True), False),  # 0-d bool array: not numeric kind
        (np.array([1.0]), False),  # 1-d
        (float("nan"), False),
        (float("inf"), False),
        (-float("inf"), False),
        (10**400, False),  # an int too large for a float
        (True, False),
        ("3", False),
    ],
)
def test_is_finite_real(value: object, expected: bool) -> None:
    assert is_finite_real(value) is expected


def test_real_number_returns_the_float() -> None:
    v = real_number("x", np.int16(3))
    assert v == 3.0 and type(v) is float
    assert real_number("x", np.array(-1.5)) == -1.5
    assert finite_float("y", 4) == 4.0 and type(finite_float("y", 4)) is float
    assert positive_float("z", 1e-9) == 1e-9
    assert check_finite("o", "n", 2) == 2.0


@pytest.mark.parametrize(
    ("kwargs", "ok", "bad"),
    [
        ({"lo": 1.0}, [1.0, 2.0], [0.999]),
        ({"lo": 1.0, "lo_open": True}, [1.000001], [1.0, 0.5]),
        ({"hi": 2.0}, [2.0, -5.0], [2.000001]),
        ({"hi": 2.0, "hi_open": True}, [1.999999], [2.0, 3.0]),
        ({"lo": 0.0, "hi": 1.0}, [0.0, 1.0, 0.5], [-0.1, 1.1]),
    ],
)
def test_real_number_bounds(kwargs: dict, ok: list[float], bad: list[float]) -> None:
    for v in ok:
        assert real_number("f", v, **kwargs) == v
    for v in bad:
        with pytest.raises(ValueError, match=r"^f = .*: must be"):
            real_number("f", v, **kwargs)


def test_real_number_messages() -> None:
    with pytest.raises(ValueError) as e:
        real_number("a.b", 0.0, lo=0.0, lo_open=True, hi=5.0, unit="m")
    assert str(e.value) == "a.b = 0.0: must be > 0.0 and <= 5.0 [m]"
    with pytest.raises(ValueError) as e:
        real_number("a.b", 6.0, lo=1.0, hi=5.0, hi_open=True)
    assert str(e.value) == "a.b = 6.0: must be >= 1.0 and < 5.0"
    with pytest.raises(ValueError) as e:
        real_number("c", 9.0, hi=5.0)
    assert str(e.value) == "c = 9.0: must be <= 5.0"
    with pytest.raises(ValueError) as e:
        real_number("c", -1.0, lo=0)
    assert str(e.value) == "c = -1.0: must be >= 0"
    with pytest.raises(ValueError) as e:
        real_number("d", float("nan"))
    assert str(e.value) == "d = nan: must be a finite number"
    with pytest.raises(ValueError) as e:
        real_number("d", "x", show=str)
    assert str(e.value) == "d = x: must be a finite number"


def test_real_number_error_classes_and_phrasing() -> None:
    # not a real number: type_error if given, else error
    with pytest.raises(TypeError) as e:
        real_number("k", "1", type_error=TypeError, phrasing="got")
    assert str(e.value) == "k must be a real number, got '1'"
    with pytest.raises(ParameterError):
        real_number("k", "1", error=ParameterError)
    # a real but non-finite number: always error, never type_error
    with pytest.raises(ParameterError) as e2:
        real_number("k", float("inf"), error=ParameterError, type_error=TypeError, phrasing="got")
    assert type(e2.value) is ParameterError
    assert str(e2.value) == "k must be finite, got inf"
    # a 0-d array holding a non-finite real is a real number, not a type error
    with pytest.raises(ParameterError) as e3:
        real_number("k", np.array(np.nan), error=ParameterError, type_error=TypeError)
    assert type(e3.value) is ParameterError
    # a 0-d bool array is not a real number
    with pytest.raises(TypeError):
        real_number("k", np.array(True), error=ParameterError, type_error=TypeError)
    # out of range: error, not type_error
    with pytest.raises(ParameterError) as e4:
        real_number("k", -1, lo=0, error=ParameterError, type_error=TypeError)
    assert type(e4.value) is ParameterError


def test_positive_and_finite_float() -> None:
    with pytest.raises(ValueError, match=r"^p = 0: must be > 0$"):
        positive_float("p", 0)
    with pytest.raises(ValueError, match=r"^p = -1e-300: must be > 0$"):
        positive_float("p", -1e-300)
    assert positive_float("p", 0.5) == 0.5
    assert finite_float("q", -7) == -7.0
    with pytest.raises(ValueError, match=r"^q = inf: must be a finite number$"):
        finite_float("q", float("inf"))


def test_check_finite() -> None:
    assert check_finite("el", "k", 0.0, lo=0.0) == 0.0
    with pytest.raises(ValueError, match=r"^el.k = 0.0: must be > 0.0$"):
        check_finite("el", "k", 0.0, lo=0.0, strict=True)
    with pytest.raises(ValueError, match=r"^el.k = -1.0: must be >= 0.0$"):
        check_finite("el", "k", -1.0, lo=0.0)
    with pytest.raises(TypeError, match=r"^el.k must be a real number, got None$"):
        check_finite("el", "k", None)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^el.k must be finite, got nan$"):
        check_finite("el", "k", float("nan"))
    assert check_finite("el", "k", -3.0) == -3.0  # no lower bound


def test_did_you_mean() -> None:
    assert did_you_mean("Stiffnes", ["stiffness", "damping"]) == "; did you mean 'stiffness'?"
    # case-insensitive, the candidate's own spelling returned; the closest of several
    assert did_you_mean("J1", ["j1", "J2x"]) == "; did you mean 'j1'?"
    assert did_you_mean("dampin", ["damping", "dumping_x"]) == "; did you mean 'damping'?"
    # ratio of "abcd" vs "abxy" is 0.5 < 0.6: no hint; "abcd" vs "abcx" is 0.75
    assert did_you_mean("abcd", ["abxy"]) == ""
    assert did_you_mean("abcd", ["abcx"]) == "; did you mean 'abcx'?"
    assert did_you_mean("zzz", []) == ""


def test_reject_unknown() -> None:
    reject_unknown("s.", {"a", "b"}, {"a", "b", "c"}, error=ParameterError)
    reject_unknown("s.", set(), {"a"}, error=ParameterError)
    with pytest.raises(ParameterError) as e:
        reject_unknown("s.", ["zeta", "alpha", "a"], {"a", "b"}, error=ParameterError)
    # the first sorted unknown key, with the allowed keys (no close match)
    assert str(e.value) == "s.alpha: unknown key; allowed: ['a', 'b']"
    with pytest.raises(ValueError) as e2:
        reject_unknown("", ["dampng"], ["damping", "mass"], error=ValueError)
    assert str(e2.value) == "dampng: unknown key; did you mean 'damping'?"


def test_check_name() -> None:
    check_name("o", "name", "x")
    for bad in ["", "   ", None, 3]:
        with pytest.raises(ValueError, match=r"^o.name = .*: must be a non-empty string$"):
            check_name("o", "name", bad)


def test_check_sequence() -> None:
    check_sequence("o", "x", (1, 2))
    check_sequence("o", "x", [1, 2])
    check_sequence("o", "x", np.array([1.0, 2.0]))
    for bad in [np.array([[1.0]]), np.array(1.0), "ab", 3, None]:
        with pytest.raises(TypeError, match=r"^o.x = .*: must be a tuple$"):
            check_sequence("o", "x", bad)


def test_store_knots() -> None:
    @dataclasses.dataclass(frozen=True)
    class K:
        x: object
        y: object

    k = K([1, np.float32(2.5)], np.array([3, 4]))
    store_knots(k, "t")
    assert k.x == (1.0, 2.5) and all(type(a) is float for a in k.x)
    assert k.y == (3.0, 4.0) and all(type(a) is float for a in k.y)
    # non-real entries are kept as they are (the table's own check names them)
    k2 = K(["a", 1], (5, 6))
    store_knots(k2, "t")
    assert k2.x == ("a", 1.0)
    assert k2.y == (5, 6) and type(k2.y[0]) is int  # a tuple is stored unchanged
    with pytest.raises(TypeError, match=r"^t.x = 1: must be a tuple$"):
        store_knots(K(1, (1,)), "t")


def test_check_type() -> None:
    check_type("o", "f", None, int)
    check_type("o", "f", 3, int)
    check_type("o", "f", 3, int, optional=False)
    with pytest.raises(TypeError) as e:
        check_type("o", "f", None, int, optional=False)
    assert str(e.value) == "o.f = None: must be a int"
    with pytest.raises(TypeError) as e:
        check_type("o", "f", "s", int)
    assert str(e.value) == "o.f = 's': must be a int or None"
