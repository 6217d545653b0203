"""Input checks shared by every layer: the one real-and-finite number check (:func:`real_number`),
names, sequences, types and the loaders' checks (unknown keys, did-you-mean hints).

Errors name the field and the offending value. :class:`ParameterError` (a :class:`ValueError`)
is the error of an invalid parameter: a parameter set's field
(:mod:`drivetrain_ctrl.plant.params`) or a table's knots (:mod:`drivetrain_ctrl.core.tables`).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Collection, Iterable
from typing import Literal

import numpy as np

__all__ = [
    "ParameterError",
    "did_you_mean",
    "reject_unknown",
    "is_real",
    "is_finite_real",
    "real_number",
]


class ParameterError(ValueError):
    """An invalid, missing or unknown parameter; the message names the dotted field path (e.g.
    ``engine.J1 = -0.2: must be > 0 [kg m^2]``) or the table and knot (``clutch.pedal_map.x[1] =
    nan: must be a finite number``). Raised by :mod:`drivetrain_ctrl.plant.params` (which
    re-exports it) and, as :class:`~drivetrain_ctrl.core.tables.TableError`, by every table."""


def is_real(value: object) -> bool:
    """True if ``value`` is a real number: an ``int``, ``float``, NumPy integer or NumPy floating
    scalar (e.g. ``np.float32(0.5)``), not a bool (finite or not: see :func:`is_finite_real`)."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


def is_finite_real(value: object) -> bool:
    """True if ``value`` is a finite real number (:func:`is_real`) or a 0-d numeric array
    holding one, not NaN or +-inf."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value[()]  # a 0-d array holds one number
    if not is_real(value):
        return False
    try:
        return math.isfinite(float(value))  # type: ignore[arg-type]
    except OverflowError:  # an int too large for a float
        return False


def real_number(
    name: str,
    value: object,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
    unit: str = "",
    error: type[Exception] = ValueError,
    type_error: type[Exception] | None = None,
    show: Callable[[object], str] = repr,
    phrasing: Literal["=", "got"] = "=",
) -> float:
    """``value`` as a ``float``, checked: a finite real number (:func:`is_finite_real`: int,
    float, NumPy scalar or 0-d array; not a bool, NaN or +-inf) within the bounds, if given.

    The one finite-number check of the package; the layers' own checks call it with their error
    class. ``lo``/``hi`` bound the value (``lo_open``/``hi_open``: strictly). ``error`` is raised
    for a non-finite or out-of-range value and ``type_error`` (``error`` if None) for a value that
    is not a real number. Messages name the field and the value (formatted by ``show``):
    ``"{name} = {value}: must be a finite number"`` and ``"{name} = {value}: must be > lo and <=
    hi [unit]"``; ``phrasing="got"`` writes the first as ``"{name} must be a real number, got
    {value}"`` (not a real number) or ``"{name} must be finite, got {value}"``.
    """
    if not is_finite_real(value):
        real = is_real(value[()] if isinstance(value, np.ndarray) and value.ndim == 0 else value)
        cls = error if real or type_error is None else type_error
        if phrasing == "got":
            what = "finite" if real else "a real number"
            raise cls(f"{name} must be {what}, got {show(value)}")
        raise cls(f"{name} = {show(value)}: must be a finite number")
    v = float(value)  # type: ignore[arg-type]
    below = lo is not None and not (v > lo if lo_open else v >= lo)
    above = hi is not None and not (v < hi if hi_open else v <= hi)
    if below or above:
        parts = []
        if lo is not None:
            parts.append(f"{'>' if lo_open else '>='} {show(lo)}")
        if hi is not None:
            parts.append(f"{'<' if hi_open else '<='} {show(hi)}")
        raise error(
            f"{name} = {show(value)}: must be {' and '.join(parts)}{f' [{unit}]' if unit else ''}"
        )
    return v


def did_you_mean(key: str, candidates: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest of ``candidates`` to ``key`` (case-insensitive,
    difflib's ratio >= 0.6), else ``""``: the one hint every misspelt-name error carries."""
    by_lower: dict[str, str] = {}
    for c in candidates:
        by_lower.setdefault(str(c).lower(), str(c))
    match = difflib.get_close_matches(str(key).lower(), list(by_lower), n=1, cutoff=0.6)
    return f"; did you mean '{by_lower[match[0]]}'?" if match else ""


def reject_unknown(
    where: str, got: Collection[str], allowed: Collection[str], *, error: type[ValueError]
) -> None:
    """Raise ``error`` naming the first (sorted) key of ``got`` not in ``allowed``, prefixed by
    ``where`` (e.g. ``"initial."``), with a did-you-mean hint or the allowed keys."""
    allowed_sorted = sorted(allowed)
    for k in sorted(set(got) - set(allowed)):
        hint = did_you_mean(k, allowed_sorted) or f"; allowed: {allowed_sorted}"
        raise error(f"{where}{k}: unknown key{hint}")


def check_name(owner: str, field_: str, value: object) -> None:
    """A name: a non-empty string."""
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"{owner}.{field_} = {value!r}: must be a non-empty string")


def check_sequence(owner: str, field_: str, value: object) -> None:
    """A tuple, list or 1-d array (of knots, names, elements)."""
    if isinstance(value, np.ndarray) and value.ndim == 1:
        return
    if not isinstance(value, (tuple, list)):
        raise TypeError(f"{owner}.{field_} = {value!r}: must be a tuple")


def store_knots(obj: object, owner: str) -> None:
    """Store ``obj.x``, ``obj.y`` (a frozen dataclass) as tuples of floats (lists and arrays in)."""
    for fld in ("x", "y"):
        v = getattr(obj, fld)
        check_sequence(owner, fld, v)
        if not isinstance(v, tuple):
            object.__setattr__(obj, fld, tuple(float(a) if is_real(a) else a for a in v))


def check_type(owner: str, field_: str, value: object, cls: type, optional: bool = True) -> None:
    if (value is None and optional) or isinstance(value, cls):
        return
    raise TypeError(
        f"{owner}.{field_} = {value!r}: must be a {cls.__name__}{' or None' if optional else ''}"
    )


def check_finite(
    owner: str, name: str, value: float, *, lo: float | None = None, strict: bool = False
) -> float:
    """:func:`real_number` for a field ``owner.name`` of a chain element: TypeError unless a real
    number, ValueError unless finite and ``>= lo`` (``> lo`` if ``strict``)."""
    return real_number(
        f"{owner}.{name}", value, lo=lo, lo_open=strict, type_error=TypeError, phrasing="got"
    )


def finite_float(name: str, v: object) -> float:
    """``v`` as a float; ValueError naming ``name`` unless it is a finite real number
    (:func:`real_number`)."""
    return real_number(name, v)


def positive_float(name: str, v: object) -> float:
    """``v`` as a float; ValueError naming ``name`` unless it is a finite number > 0
    (:func:`real_number`)."""
    return real_number(name, v, lo=0, lo_open=True)
