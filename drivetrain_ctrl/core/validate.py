"""Input checks shared by every layer: real and finite numbers, names, sequences, types and
input checks shared by the loaders (unknown keys, finite numbers)."""

from __future__ import annotations

import difflib
import math
from collections.abc import Collection, Iterable

import numpy as np

__all__ = [
    "did_you_mean",
    "reject_unknown",
    "is_real",
    "is_finite_real",
]


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
) -> None:
    if not is_real(value):
        raise TypeError(f"{owner}.{name} must be a real number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{owner}.{name} must be finite, got {value!r}")
    if lo is not None and (value <= lo if strict else value < lo):
        raise ValueError(f"{owner}.{name} = {value!r}: must be {'>' if strict else '>='} {lo}")


def finite_float(name: str, v: object) -> float:
    """``v`` as a float; ValueError naming ``name`` unless it is a finite real number."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} = {v!r}: must be a finite number")
    f = float(v)
    if not math.isfinite(f):
        raise ValueError(f"{name} = {v!r}: must be a finite number")
    return f


def positive_float(name: str, v: object) -> float:
    """``v`` as a float; ValueError naming ``name`` unless it is a finite number > 0."""
    f = finite_float(name, v)
    if not f > 0:
        raise ValueError(f"{name} = {v!r}: must be > 0")
    return f
