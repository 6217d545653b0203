"""The PI/PID controller structure shared by the design tools (one implementation).

Continuous (``dt = 0``): ``C = kp + ki/s + kd s/(tf s + 1)``. Sampled (``dt`` [s] > 0): ``C = kp
+ ki I(z) + kd (z - 1)/((tf + dt) z - tf)``, a backward-Euler derivative filter and the discrete
integrator ``I(z)`` named by ``integrator`` (:data:`INTEGRATORS`):

* ``"forward"`` (the default, MATLAB's; the integrator of the shipped ``pi``/``pi-10ms``
  controllers): ``I = dt/(z - 1)``;
* ``"backward"``: ``I = dt z/(z - 1)``;
* ``"tustin"``: ``I = (dt/2) (z + 1)/(z - 1)``.

``kd = 0`` is a PI. Units: ``kp`` [u/y], ``ki`` [u/(y s)], ``kd`` [u s/y], ``tf`` [s].
"""

from __future__ import annotations

from typing import Any

import control
import numpy as np
from numpy.typing import NDArray

from ..core.validate import real_number

__all__ = ["INTEGRATORS", "check_integrator", "integrator_response", "pid_basis", "pid_controller"]

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]

#: the discrete integrators of a sampled PI/PID (module docstring)
INTEGRATORS: tuple[str, ...] = ("forward", "backward", "tustin")


def check_integrator(integrator: object, where: str = "integrator") -> str:
    """``integrator`` if it is one of :data:`INTEGRATORS`, else a ValueError naming it."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"{where} = {integrator!r}: must be one of {INTEGRATORS}")
    return str(integrator)


def _integrator_num(dt: float, integrator: str) -> F64:
    """The numerator of ``I(z)`` over ``z - 1`` (module docstring)."""
    return {
        "forward": np.array([0.0, dt]),
        "backward": np.array([dt, 0.0]),
        "tustin": np.array([dt / 2, dt / 2]),
    }[integrator]


def integrator_response(w: Any, dt: float, integrator: str = "forward") -> C128:
    """``1/(jw)`` (``dt = 0``) or ``I(exp(jw dt))`` of ``integrator`` at the frequencies ``w``
    [rad/s] (complex array)."""
    w = np.asarray(w, dtype=float)
    if dt == 0.0:
        return np.asarray(1.0 / (1j * w), dtype=complex)
    z = np.exp(1j * w * dt)
    n = _integrator_num(dt, integrator)
    return np.asarray((n[0] * z + n[1]) / (z - 1.0), dtype=complex)


def pid_basis(structure: str, dt: float, tf: float, integrator: str) -> tuple[list[F64], F64]:
    """Numerators (one per gain kp, ki[, kd] of ``structure`` ``"pi"`` or ``"pid"``) over one
    common denominator, so that ``C = sum_i theta_i n_i / d``; continuous in ``s``, discrete in
    ``z``; all of the denominator's length."""
    pid = structure == "pid"
    if dt == 0.0:
        d = np.array([1.0, 0.0])  # s
        nums = [np.array([1.0, 0.0]), np.array([0.0, 1.0])]  # kp, ki / s
        if pid:
            f = np.array([tf, 1.0])
            d = np.polymul(d, f)
            nums = [np.polymul(n, f) for n in nums]
            nums.append(np.array([1.0, 0.0, 0.0]))  # kd s^2 / (s (tf s + 1))
        return _padded(nums, d), d
    d = np.array([1.0, -1.0])  # z - 1
    nums = [np.array([1.0, -1.0]), _integrator_num(dt, integrator)]
    if pid:
        f = np.array([tf + dt, -tf])
        d = np.polymul(d, f)
        nums = [np.polymul(n, f) for n in nums]
        nums.append(np.polymul([1.0, -1.0], [1.0, -1.0]))  # kd (z-1)^2 / ((z-1) f)
    return _padded(nums, d), d


def _padded(nums: list[Any], d: F64) -> list[F64]:
    """Numerators as float arrays of the denominator's length (leading zeros)."""
    out = []
    for n in nums:
        n = np.asarray(n, dtype=float)
        out.append(np.concatenate([np.zeros(d.size - n.size), n]))
    return out


def pid_controller(
    kp: float,
    ki: float,
    kd: float = 0.0,
    *,
    tf: float = 0.0,
    dt: float = 0.0,
    integrator: str = "forward",
) -> control.TransferFunction:
    """The PI/PID controller (module docstring) as a python-control transfer function.

    ``kd = 0`` gives a PI (first order), ``ki = kd = 0`` the static gain ``kp``. A continuous
    PID needs ``tf > 0``. Units: kp [u/y], ki [u/(y s)], kd [u s/y], tf [s], dt [s]."""
    kp = real_number("kp", kp)
    ki = real_number("ki", ki)
    kd = real_number("kd", kd)
    dt = real_number("dt", dt, lo=0.0, unit="s")
    tf = real_number("tf", tf, lo=0.0, unit="s")
    integrator = check_integrator(integrator)
    if ki == 0.0 and kd == 0.0:
        return control.tf([kp], [1.0], dt)
    structure = "pid" if kd != 0.0 else "pi"
    if structure == "pid" and dt == 0.0 and tf <= 0.0:
        raise ValueError(f"tf = {tf!r}: a continuous PID needs a derivative filter tf > 0 [s]")
    nums, d = pid_basis(structure, dt, tf, integrator)
    gains = (kp, ki, kd)[: len(nums)]
    num = sum(g * n for g, n in zip(gains, nums, strict=True))
    return control.tf(np.trim_zeros(np.asarray(num), "f") if np.any(num) else [0.0], d, dt)
