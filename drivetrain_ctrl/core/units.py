"""SI constants and unit conversions used at the edges of the toolbox.

Everything inside :mod:`drivetrain_ctrl` is in SI units (m, kg, s, rad, N, N m). Engineering units
such as rpm and km/h appear only at the edges (user input, plots, reports); convert them here.

Every conversion accepts a Python/NumPy scalar (returns a ``float``) or an array-like of numbers
(returns a new ``numpy.ndarray`` of ``float64``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "GRAVITY",
    "RPM_TO_RAD_S",
    "KMH_TO_M_S",
    "RAD_S_TO_RPM",
    "M_S_TO_KMH",
    "rpm_to_rad_s",
    "rad_s_to_rpm",
    "kmh_to_m_s",
    "m_s_to_kmh",
]

#: Gravitational acceleration used throughout the toolbox [m/s^2]. The paper's ``g``; rounded
#: to 9.81 (not the standard 9.80665) so that hand calculations in the reference documents match.
GRAVITY: float = 9.81

#: One revolution per minute expressed in rad/s [rad/s per rpm] (= 2 pi / 60).
RPM_TO_RAD_S: float = math.pi / 30.0

#: One kilometre per hour expressed in m/s [m/s per km/h] (= 1 / 3.6).
KMH_TO_M_S: float = 1.0 / 3.6

#: One rad/s expressed in rpm [rpm per rad/s] (= 60 / (2 pi)); for scaling signals and arrays.
RAD_S_TO_RPM: float = 30.0 / math.pi

#: One m/s expressed in km/h [km/h per m/s].
M_S_TO_KMH: float = 3.6

_ArrayIn = NDArray[Any] | Sequence[float]


def _is_scalar(x: object) -> bool:
    return isinstance(x, int | float | np.number) or (isinstance(x, np.ndarray) and x.ndim == 0)


@overload
def rpm_to_rad_s(x: float) -> float: ...
@overload
def rpm_to_rad_s(x: _ArrayIn) -> NDArray[np.float64]: ...
def rpm_to_rad_s(x: float | _ArrayIn) -> float | NDArray[np.float64]:
    """Convert a rotational speed from rpm [rev/min] to rad/s [rad/s]."""
    if _is_scalar(x):
        return float(x) * math.pi / 30.0  # type: ignore[arg-type]
    return np.asarray(x, dtype=np.float64) * (math.pi / 30.0)


@overload
def rad_s_to_rpm(x: float) -> float: ...
@overload
def rad_s_to_rpm(x: _ArrayIn) -> NDArray[np.float64]: ...
def rad_s_to_rpm(x: float | _ArrayIn) -> float | NDArray[np.float64]:
    """Convert a rotational speed from rad/s [rad/s] to rpm [rev/min]."""
    if _is_scalar(x):
        return float(x) * 30.0 / math.pi  # type: ignore[arg-type]
    return np.asarray(x, dtype=np.float64) * (30.0 / math.pi)


@overload
def kmh_to_m_s(x: float) -> float: ...
@overload
def kmh_to_m_s(x: _ArrayIn) -> NDArray[np.float64]: ...
def kmh_to_m_s(x: float | _ArrayIn) -> float | NDArray[np.float64]:
    """Convert a speed from km/h [km/h] to m/s [m/s]."""
    if _is_scalar(x):
        return float(x) / 3.6  # type: ignore[arg-type]
    return np.asarray(x, dtype=np.float64) / 3.6


@overload
def m_s_to_kmh(x: float) -> float: ...
@overload
def m_s_to_kmh(x: _ArrayIn) -> NDArray[np.float64]: ...
def m_s_to_kmh(x: float | _ArrayIn) -> float | NDArray[np.float64]:
    """Convert a speed from m/s [m/s] to km/h [km/h]."""
    if _is_scalar(x):
        return float(x) * 3.6  # type: ignore[arg-type]
    return np.asarray(x, dtype=np.float64) * 3.6
