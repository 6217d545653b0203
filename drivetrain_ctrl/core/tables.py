"""The one piecewise-linear table type (breakpoints and values, linear between, clamped outside)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .validate import check_finite, store_knots


@dataclass(frozen=True, slots=True)
class PwlTable:
    """Piecewise-linear table ``y(x)``, clamped to the end values outside ``[x_0, x_last]``.

    ``x`` strictly increasing. A single knot is a constant. Knots are breakpoints: the simulator
    never integrates across one.
    """

    x: tuple[float, ...]
    y: tuple[float, ...]
    name: str = "table"

    def __post_init__(self) -> None:
        store_knots(self, self.name)
        if len(self.x) != len(self.y) or not self.x:
            raise ValueError(
                f"{self.name}: x and y must be non-empty and of equal length, got {len(self.x)} "
                f"x and {len(self.y)} y"
            )
        for i, (a, b) in enumerate(zip(self.x, self.y, strict=True)):
            check_finite(self.name, f"x[{i}]", a)
            check_finite(self.name, f"y[{i}]", b)
        for i in range(1, len(self.x)):
            if not self.x[i] > self.x[i - 1]:
                raise ValueError(
                    f"{self.name}: x must be strictly increasing, x[{i}]={self.x[i]} <= "
                    f"x[{i - 1}]={self.x[i - 1]}"
                )

    def __call__(self, v: float) -> float:
        """The table at ``v``: linear between knots, the end values beyond them (NaN for NaN)."""
        return float(np.interp(v, self.x, self.y))


def _pwl_clamped(t: PwlTable) -> tuple[list[float], list[float], list[float]]:
    """Bounds, slopes, offsets of a clamped PWL table."""
    x, y = t.x, t.y
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
