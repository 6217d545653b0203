"""The one piecewise-linear table type, :class:`PwlTable`: breakpoints and values, linear between.

One type serves every table of the package: the chain elements' tables (a friction capacity or
mu(slip), an engine's gain; clamped, evaluated by the kernels in the bounds/slopes/offsets form of
:meth:`PwlTable.segments`), a controller block's lookup, and the parameter set's maps (full-load
curve, pedal-map shape, mu(slip), damper spring), which carry axis names and units and may be
odd or even and extrapolated linearly. ``drivetrain_ctrl.plant.params.Table`` is this class under
its older name.

Bad knots or options raise :class:`TableError` (a
:class:`~drivetrain_ctrl.core.validate.ParameterError`, hence a :class:`ValueError`), or
:class:`TableTypeError` (also a :class:`TypeError`) for knots or labels of the wrong type; the
message names the table and the knot.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import KW_ONLY, dataclass
from typing import Any, TypeAlias, overload

import numpy as np
from numpy.typing import NDArray

from .validate import ParameterError, real_number

__all__ = ["PwlTable", "TableError", "TableTypeError", "EXTRAPOLATIONS", "SYMMETRIES"]

#: admissible ``extrapolation`` options: hold the end values, or continue the end segments
EXTRAPOLATIONS: tuple[str, ...] = ("clamp", "linear")
#: admissible ``symmetry`` options: none, ``sign(v) f(|v|)`` (odd) or ``f(|v|)`` (even)
SYMMETRIES: tuple[str, ...] = ("none", "odd", "even")

FloatOrArray: TypeAlias = float | NDArray[np.float64]


class TableError(ParameterError):
    """Invalid knots or options of a :class:`PwlTable`; the message names the table (its
    ``name``) and the knot. A :class:`~drivetrain_ctrl.core.validate.ParameterError`, so a
    parameter file's bad table is reported like any bad parameter."""


class TableTypeError(TableError, TypeError):
    """Knots, labels or options of the wrong type (e.g. ``x = None`` or a string knot): a
    :class:`TableError` that is also a :class:`TypeError`."""


def _knots(name: str, axis: str, value: object) -> tuple[float, ...]:
    """``value`` (a tuple, list or 1-d array of finite real numbers) as a tuple of floats."""
    if isinstance(value, np.ndarray) and value.ndim == 1:
        value = value.tolist()
    if not isinstance(value, tuple | list):
        raise TableTypeError(
            f"{name}.{axis} = {value!r}: must be a tuple, list or 1-d array of numbers"
        )
    return tuple(
        real_number(f"{name}.{axis}[{i}]", v, error=TableError, type_error=TableTypeError)
        for i, v in enumerate(value)
    )


@dataclass(frozen=True, slots=True)
class PwlTable:
    """Piecewise-linear table ``y(x)``, linear between the knots.

    ``x`` strictly increasing, ``y`` of the same length (a single knot is a constant); tuples,
    lists or 1-d arrays of finite numbers, stored as tuples of floats. Knots are breakpoints: the
    simulator never integrates across one. ``name`` names the table in error messages (a chain
    element's field, or a parameter's dotted path).

    Keyword-only options, used by the parameter set's maps (the defaults are those of the
    chain elements' and controllers' tables):

    * ``x_name``, ``x_unit``, ``y_name``, ``y_unit``: labels of the axes (``"-"``: no unit);
    * ``extrapolation``: ``"clamp"`` (default) holds the end values outside ``[x_0, x_last]``,
      ``"linear"`` continues the end segments with their slopes;
    * ``symmetry``: ``"none"`` (default); ``"odd"`` evaluates ``sign(v) * f(|v|)`` and
      ``"even"`` ``f(|v|)``, so such tables need knots for ``x >= 0`` only.

    Evaluation (:meth:`__call__`) follows :func:`numpy.interp` inside the knot range.
    """

    x: tuple[float, ...]
    y: tuple[float, ...]
    name: str = "table"
    _: KW_ONLY
    x_name: str = "x"
    x_unit: str = "-"
    y_name: str = "y"
    y_unit: str = "-"
    extrapolation: str = "clamp"
    symmetry: str = "none"

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise TableTypeError(f"PwlTable.name = {self.name!r}: must be a non-empty str")
        name = self.name
        for label in ("x_name", "x_unit", "y_name", "y_unit"):
            if not isinstance(getattr(self, label), str):
                raise TableTypeError(f"{name}.{label} = {getattr(self, label)!r}: must be a str")
        xs, ys = _knots(name, "x", self.x), _knots(name, "y", self.y)
        if not xs or not ys:
            raise TableError(
                f"{name}: x and y must be non-empty (a table needs at least one point), got "
                f"{len(xs)} x and {len(ys)} y"
            )
        if len(xs) != len(ys):
            raise TableError(
                f"{name}: x and y must have the same length, got {len(xs)} x and {len(ys)} y"
            )
        for i in range(1, len(xs)):
            if not xs[i] > xs[i - 1]:
                raise TableError(
                    f"{name}: {self.x_name} must be strictly increasing, but x[{i}]={xs[i]!r} "
                    f"<= x[{i - 1}]={xs[i - 1]!r}"
                )
        if self.extrapolation not in EXTRAPOLATIONS:
            raise TableError(
                f"{name}.extrapolation = {self.extrapolation!r}: must be one of {EXTRAPOLATIONS}"
            )
        if self.symmetry not in SYMMETRIES:
            raise TableError(f"{name}.symmetry = {self.symmetry!r}: must be one of {SYMMETRIES}")
        object.__setattr__(self, "x", xs)
        object.__setattr__(self, "y", ys)

    def x_array(self) -> NDArray[np.float64]:
        """The knot abscissae as a new NumPy array [``x_unit``]."""
        return np.array(self.x, dtype=np.float64)

    def y_array(self) -> NDArray[np.float64]:
        """The knot ordinates as a new NumPy array [``y_unit``]."""
        return np.array(self.y, dtype=np.float64)

    @overload
    def __call__(self, v: float) -> float: ...
    @overload
    def __call__(self, v: NDArray[Any] | Sequence[float]) -> NDArray[np.float64]: ...
    def __call__(self, v: float | NDArray[Any] | Sequence[float]) -> FloatOrArray:
        """The table at ``v`` [``x_unit``], in [``y_unit``]: a ``float`` for a scalar, an array
        of the same shape for an array-like; NaN for NaN (not an end value)."""
        a = np.asarray(v, dtype=np.float64)
        u = a if self.symmetry == "none" else np.abs(a)
        xs, ys = self.x, self.y
        out = np.interp(u, xs, ys)
        if self.extrapolation == "linear" and len(xs) >= 2:
            lo_slope = (ys[1] - ys[0]) / (xs[1] - xs[0])
            hi_slope = (ys[-1] - ys[-2]) / (xs[-1] - xs[-2])
            out = np.where(u < xs[0], ys[0] + lo_slope * (u - xs[0]), out)
            out = np.where(u > xs[-1], ys[-1] + hi_slope * (u - xs[-1]), out)
        if self.symmetry == "odd":
            out = np.sign(a) * out
        if out.ndim == 0:
            return float(out)
        return np.asarray(out, dtype=np.float64)

    def segments(self) -> tuple[list[float], list[float], list[float]]:
        """The kernels' form of a clamped table: ``bounds`` (the knots), ``slopes`` and ``offsets``
        with ``y = slopes[r] * v + offsets[r]`` in region ``r = bisect_left(bounds, v)`` (region 0
        below the first knot and the last above the last knot are flat). Only for
        ``extrapolation="clamp"``, ``symmetry="none"`` (the chain elements' and controllers'
        tables); TableError otherwise."""
        if self.extrapolation != "clamp" or self.symmetry != "none":
            raise TableError(
                f"{self.name}: the kernels evaluate clamped tables without symmetry, got "
                f"extrapolation = {self.extrapolation!r}, symmetry = {self.symmetry!r}"
            )
        x, y = self.x, self.y
        if len(x) == 1:
            return [], [0.0], [y[0]]
        bounds = list(x)
        slopes = [0.0]
        offs = [y[0]]
        for k in range(len(x) - 1):
            s = (y[k + 1] - y[k]) / (x[k + 1] - x[k])
            slopes.append(s)
            offs.append(y[k] - s * x[k])
        slopes.append(0.0)
        offs.append(y[-1])
        return bounds, slopes, offs


def _pwl_clamped(t: PwlTable) -> tuple[list[float], list[float], list[float]]:
    """Bounds, slopes, offsets of a clamped table: :meth:`PwlTable.segments` (a module-level name
    the model compiler calls, so that a test can replace it)."""
    return t.segments()
