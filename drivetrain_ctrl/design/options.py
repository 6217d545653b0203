"""Option handling shared by the design tools' spec dataclasses (:class:`~.robust.RobustSpec`,
:class:`~.hinf.HinfSpec`): keyword options over a base spec, and a given frequency grid."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

from ..core.validate import did_you_mean

__all__ = ["spec_with_options", "frequency_vector"]

SpecT = TypeVar("SpecT")


def spec_with_options(
    cls: type[SpecT], where: str, spec: SpecT | None, options: Mapping[str, Any]
) -> SpecT:
    """``spec`` (default: ``cls()``) with the fields in ``options`` replaced; an unknown option is
    a ValueError naming ``where``, the key and the value (with a did-you-mean hint), a ``spec``
    of another type a TypeError."""
    if spec is not None and not isinstance(spec, cls):
        raise TypeError(f"{where}: spec = {spec!r}: must be a {cls.__name__} or None")
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    for k, v in options.items():
        if k not in names:
            hint = did_you_mean(k, names) or f"; options: {names}"
            raise ValueError(f"{where}: unknown option {k} = {v!r}{hint}")
    return dataclasses.replace(spec if spec is not None else cls(), **options)  # type: ignore[type-var]


def frequency_vector(name: str, value: Any, min_points: int) -> tuple[float, ...]:
    """A given frequency grid [rad/s] as a tuple: 1-D, at least ``min_points`` frequencies,
    finite, > 0 and strictly increasing (else a ValueError naming ``name`` and the value)."""
    try:
        w = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} = {value!r}: a 1-D grid [rad/s] is needed") from exc
    if w.ndim != 1 or w.size < min_points:
        raise ValueError(f"{name} = {value!r}: a 1-D grid of >= {min_points} frequencies [rad/s]")
    if not (np.all(np.isfinite(w)) and np.all(w > 0) and np.all(np.diff(w) > 0)):
        raise ValueError(
            f"{name} = {value!r}: frequencies must be finite, > 0 and strictly increasing [rad/s]"
        )
    return tuple(float(x) for x in w)
