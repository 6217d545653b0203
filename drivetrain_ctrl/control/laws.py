"""Clutch start controllers by name or from a TOML file: law (6), its PI variant and any LTI law.

A :class:`ControllerSpec` is data only (what the user chose); :meth:`ControllerSpec.build` turns it
into a :class:`~drivetrain_ctrl.control.blocks.Controller` for a drivetrain and a scenario's reference.
The same :class:`Controller` serves the simulation (``simulate(..., controller=...)``) and the linear
analysis (its ``lti``).

Built-in controllers (:func:`builtin_controllers`), TOML files shipped in ``control/builtin/``:

``paper``
    The paper's law (6), continuous: ``x_r = x_r0 + k_r (omega_r - omega_1) sgn(omega_1 - omega_3)``
    with the paper's gains (Section IV): ``x_r0`` = 0.07 m, ``k_r`` = 3e-4 m s/rad.
``pi``
    A PI variant on the same signed error, ``x_r = x_r0 + sgn(.) (k_p e + k_i int e)``, with
    anti-windup (the integrator holds while the actuator stroke saturates).
``paper-10ms``, ``pi-10ms``
    The same, sampled every 10 ms with a transport delay of one sample (a transmission control
    unit).
``robust-pi``, ``hinf``
    Designed controllers (``law = "pi"``, ``law = "lti"``), written by ``drivetrain-ctrl design``
    from the design specs of the same name (:mod:`drivetrain_ctrl.design.from_spec`); their
    ``[design]`` table holds the spec and the achieved figures.

Measured speeds: the controller measures omega_1 (engine) and omega_3 (primary shaft) as in the
paper. In the reduced model omega_3 is the primary-shaft speed, and the clutch slip is omega_1 -
omega_3. In the full model the clutch slip itself is omega_1 - omega_2 (engine minus clutch disc);
the disc and the primary shaft are separated by the torsional damper, so omega_3 (``omega_primary``)
can differ slightly from the disc speed while the damper winds up. The sign switch uses
``omega_engine - omega_primary`` in both models.

At the clutch's lock event the output latches and moves without a jump from its current value to
full engagement (the pedal map's engaged end) at ``engage_rate`` [m/s]; if the clutch slips again the
controller re-arms, continuing from the current x_r (see :mod:`drivetrain_ctrl.control.blocks`).

A controller file (TOML; unknown keys are errors naming the key)::

    name = "my-pi"
    law = "pi"                 # "paper" (law 6), "pi" or "lti"
    k_r = 3.0e-4               # [m s/rad] paper law gain (default: the built-in paper's)
    x_r0 = 0.07                # [m] output at zero error (default: the built-in paper's)
    kp = 3.0e-4                # [m s/rad] PI proportional gain
    ki = 1.5e-3                # [m/rad] PI integral gain
    sample_period_s = 0.01     # optional: sampled controller
    delay_samples = 1          # transport delay in samples (sampled only)
    engage_rate_m_s = 0.05     # latch ramp rate after lock-up
    rate_limit_m_s = 0.5       # optional actuator rate limit
    anti_windup = true
    back_calculation_time_s = 0.2   # optional [s]: back-calculation time constant T_t ("pi", "lti")

    [design]                   # optional, free-form: the design spec and figures that produced
    method = "robust-pi"       # the controller (provenance; kept as read, shown in reports)

A general LTI law (``law = "lti"``) acts like the PI on the same signed speed error,
``x_r = x_r0 + sgn(omega_1 - omega_3) C e``, ``e = omega_r - omega_1``, with any proper SISO
``C`` (from the error [rad/s] to x_r - x_r0 [m]) given either as transfer-function coefficients
(descending powers of s, or of z when ``sample_period_s`` is given)::

    law = "lti"
    num = [1.0e-3, 5.0e-3]     # C(s) = (1e-3 s + 5e-3) / s: the built-in PI
    den = [1.0, 0.0]

or as state-space matrices (``A`` n x n, ``B`` and ``C`` n-vectors, ``D`` a number; in discrete
time when ``sample_period_s`` is given; ``A = []``, ``B = []``, ``C = []`` for a static gain)::

    law = "lti"
    A = [[0.0]]
    B = [1.0]
    C = [5.0e-3]
    D = 1.0e-3

Anti-windup of an LTI law (back-calculation, :mod:`drivetrain_ctrl.control.blocks`): the correction
acts along ``C^T`` and pulls the value before the saturation back to the limit with time constant
``back_calculation_time_s``. Without that key the time is derived as for the PI when the controller has
exactly one integrator (a pole at s = 0, or z = 1, within a relative 1e-9): ``T_t = k_p/k_i``,
``k_i`` the integrator's residue (per second) and ``k_p`` the value at s = 0 (z = 1) of the rest of
``C`` (for a PID with a derivative filter: its proportional gain), at least
:data:`MIN_ANTI_WINDUP_TIME_S`; a controller without an integrator needs none (``None``), and one
with several integrators must give ``back_calculation_time_s`` or set ``anti_windup = false``. A slow
pole that is not an integrator (e.g. an H-infinity controller's -1e-4 rad/s) counts as none: give
the time explicitly. The LTI states also freeze before the start and while the latch holds, as
for the PI.

A spec is written back to TOML by :meth:`ControllerSpec.to_toml` (:func:`save_controller`); floats
are written with ``repr``, so ``load_controller(spec.to_toml(path)) == spec`` with bitwise-equal
coefficients. :func:`spec_from_lti` makes an ``"lti"`` spec from a python-control system.

Law (6)'s gains are controller settings, not plant parameters: a spec that leaves ``k_r`` or
``x_r0`` out takes the built-in ``paper`` controller's value (:func:`law6_defaults`, read from
``control/builtin/paper.toml``). ``x_r0`` must lie within the actuator stroke of the parameter set
the controller is built for (checked by :meth:`ControllerSpec.build`).
"""

from __future__ import annotations

import functools
import json
import math
import re
import warnings
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import control
import numpy as np
import scipy.signal
from numpy.typing import NDArray

from ..core.registry import builtin_files, load_builtin_or_toml, load_toml_as, read_toml
from ..core.signals import Signal
from ..core.validate import (
    did_you_mean,
    finite_float,
    is_finite_real,
    positive_float,
    real_number,
    reject_unknown,
)
from ..plant.drivetrain import clutch_friction
from ..plant.params import DrivetrainParams
from .blocks import Actuator, Controller, LatchRamp, actuator_tf

__all__ = [
    "UnstableLoopWarning",
    "slip_loop",
    "ControllerError",
    "ControllerSpec",
    "builtin_controllers",
    "controller_from_dict",
    "law6_defaults",
    "load_controller",
    "save_controller",
    "spec_from_lti",
    "LAWS",
    "GAIN_RANGE",
    "STABILITY_CACHE_SIZE",
]

#: control laws a spec can name
LAWS: tuple[str, ...] = ("paper", "pi", "lti")

#: accepted magnitude of a gain [m s/rad or m/rad]; beyond it the value is surely a unit error
GAIN_RANGE: tuple[float, float] = (0.0, 1.0)

#: (min, max) of the sample period [s]
SAMPLE_PERIOD_RANGE: tuple[float, float] = (1e-5, 0.5)

#: smallest back-calculation time constant [s] of the PI anti-windup
MIN_ANTI_WINDUP_TIME_S: float = 0.01

#: largest transport delay [samples]
MAX_DELAY_SAMPLES: int = 100

#: largest order (number of states) of an ``"lti"`` law
MAX_LTI_ORDER: int = 30

#: a controller pole within this distance of s = 0 (z = 1), relative to max(1, |A|), is an
#: integrator (for the anti-windup rule of an ``"lti"`` law)
INTEGRATOR_TOL: float = 1e-9

#: the coefficient fields of an ``"lti"`` law: transfer function or state space
_TF_FIELDS: tuple[str, ...] = ("num", "den")
_SS_FIELDS: tuple[str, ...] = ("A", "B", "C", "D")


class ControllerError(ValueError):
    """A controller spec or file is invalid (the message names the field and the value)."""


class UnstableLoopWarning(UserWarning):
    """The slip-mode loop of a controller is unstable at its nominal operating point."""


def _finite(where: str, name: str, v: Any, lo: float, hi: float, *, lo_open: bool = False) -> float:
    """``v`` as a float within ``[lo, hi]`` (``(lo, hi]`` if ``lo_open``), else ControllerError
    naming ``where + name`` and the value (:func:`~drivetrain_ctrl.core.validate.real_number`)."""
    return real_number(f"{where}{name}", v, lo=lo, hi=hi, lo_open=lo_open, error=ControllerError)


@dataclass(frozen=True, kw_only=True)
class ControllerSpec:
    """A clutch start controller, as data (see the module docstring for the fields' meaning).

    Units: ``k_r``, ``kp`` [m s/rad]; ``ki`` [m/rad]; ``x_r0`` [m]; ``sample_period_s`` [s];
    ``engage_rate_m_s``, ``rate_limit_m_s`` [m/s]; ``back_calculation_time_s`` [s]. ``None`` for
    ``k_r``/``x_r0`` takes the built-in ``paper`` controller's values (:func:`law6_defaults`);
    :attr:`gain_k_r`, :attr:`offset_x_r0` are the values used.

    Law ``"lti"``: ``num``/``den`` (transfer function, descending powers of s or z) or ``A``,
    ``B``, ``C``, ``D`` (state space; ``B``, ``C`` vectors, ``D`` a number), from the error
    [rad/s] to x_r - x_r0 [m]; discrete (z) when ``sample_period_s`` is given. Lists and arrays
    are stored as tuples of floats. ``design`` is a free-form table (provenance: the design spec
    and figures that produced the controller), kept as given with NumPy scalars and arrays turned
    into plain numbers and lists, so that it round-trips through TOML; it takes no part in
    hashing.
    """

    name: str
    law: str = "paper"
    k_r: float | None = None
    x_r0: float | None = None
    kp: float | None = None
    ki: float | None = None
    sample_period_s: float | None = None
    delay_samples: int = 0
    engage_rate_m_s: float = 0.05
    rate_limit_m_s: float | None = None
    anti_windup: bool = True
    back_calculation_time_s: float | None = None
    num: tuple[float, ...] | None = None
    den: tuple[float, ...] | None = None
    A: tuple[tuple[float, ...], ...] | None = None
    B: tuple[float, ...] | None = None
    C: tuple[float, ...] | None = None
    D: float | None = None
    design: dict[str, Any] | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ControllerError(f"controller name = {self.name!r}: must be a non-empty string")
        w = f"controller {self.name!r}: "
        if self.law not in LAWS:
            hint = did_you_mean(str(self.law), LAWS)
            raise ControllerError(f"{w}law = {self.law!r}: known laws {LAWS}{hint}")
        lo, hi = GAIN_RANGE
        if self.k_r is not None:
            _finite(w, "k_r", self.k_r, lo, hi, lo_open=True)
        if self.x_r0 is not None:
            _finite(w, "x_r0", self.x_r0, -1.0, 1.0)
        if self.law == "pi":
            if self.kp is None or self.ki is None:
                raise ControllerError(f"{w}law 'pi' needs kp and ki")
            _finite(w, "kp", self.kp, lo, hi)
            _finite(w, "ki", self.ki, lo, hi)
            if self.kp == 0 and self.ki == 0:
                raise ControllerError(
                    f"{w}kp = {self.kp!r}, ki = {self.ki!r}: at least one PI gain must be > 0 "
                    "(with both zero the controller does nothing)"
                )
        elif self.kp is not None or self.ki is not None:
            uses = "k_r" if self.law == "paper" else "num/den or A, B, C, D"
            raise ControllerError(f"{w}kp/ki are PI gains; law {self.law!r} uses {uses}")
        if self.law != "paper" and self.k_r is not None:
            raise ControllerError(
                f"{w}k_r = {self.k_r!r}: law (6)'s gain; law {self.law!r} has none"
            )
        self._check_lti_fields(w)
        if self.sample_period_s is not None:
            _finite(w, "sample_period_s", self.sample_period_s, *SAMPLE_PERIOD_RANGE)
        d = self.delay_samples
        if (
            isinstance(d, bool)
            or not isinstance(d, (int, np.integer))
            or not 0 <= d <= MAX_DELAY_SAMPLES
        ):
            raise ControllerError(
                f"{w}delay_samples = {d!r}: must be an integer in [0, {MAX_DELAY_SAMPLES}]"
            )
        if d and self.sample_period_s is None:
            raise ControllerError(f"{w}delay_samples = {d}: needs sample_period_s")
        _finite(w, "engage_rate_m_s", self.engage_rate_m_s, 0.0, 10.0, lo_open=True)
        if self.rate_limit_m_s is not None:
            _finite(w, "rate_limit_m_s", self.rate_limit_m_s, 0.0, 100.0, lo_open=True)
        if not isinstance(self.anti_windup, bool):
            raise ControllerError(f"{w}anti_windup = {self.anti_windup!r}: must be true or false")
        if self.back_calculation_time_s is not None:
            if self.law == "paper":
                raise ControllerError(
                    f"{w}back_calculation_time_s = {self.back_calculation_time_s!r}: law 'paper' has no "
                    "integrator to wind up"
                )
            if not self.anti_windup:
                raise ControllerError(
                    f"{w}back_calculation_time_s = {self.back_calculation_time_s!r} with anti_windup = "
                    "false: leave one out"
                )
            _finite(
                w, "back_calculation_time_s", self.back_calculation_time_s, 0.0, 1e3, lo_open=True
            )
        if self.design is not None:
            if not isinstance(self.design, dict):
                raise ControllerError(
                    f"{w}design = {self.design!r}: must be a table (dict) of provenance entries"
                )
            object.__setattr__(self, "design", _toml_value(f"{w}design", self.design))
        if self.law == "lti":
            self._lti_anti_windup(w)  # an "lti" law whose rule cannot apply fails here

    def _check_lti_fields(self, w: str) -> None:
        """Check and store the coefficients of an ``"lti"`` law (tuples of floats)."""
        tf_given = [k for k in _TF_FIELDS if getattr(self, k) is not None]
        ss_given = [k for k in _SS_FIELDS if getattr(self, k) is not None]
        if self.law != "lti":
            if tf_given or ss_given:
                k = (tf_given + ss_given)[0]
                raise ControllerError(
                    f"{w}{k} = {getattr(self, k)!r}: coefficients of law 'lti'; law "
                    f"{self.law!r} takes none"
                )
            return
        if tf_given and ss_given:
            raise ControllerError(
                f"{w}law 'lti': give num/den or A, B, C, D, not both (got {tf_given + ss_given})"
            )
        if not tf_given and not ss_given:
            raise ControllerError(
                f"{w}law 'lti' needs its coefficients: num and den (transfer function) or A, B, "
                "C, D (state space)"
            )
        if tf_given:
            for k in _TF_FIELDS:
                if getattr(self, k) is None:
                    raise ControllerError(f"{w}{k}: missing (law 'lti' with {tf_given[0]})")
            num = _float_vector(w, "num", self.num)
            den = _float_vector(w, "den", self.den)
            if not num or not den:
                raise ControllerError(
                    f"{w}num = {list(num)!r}, den = {list(den)!r}: need at least one coefficient"
                )
            if den[0] == 0.0:
                raise ControllerError(
                    f"{w}den[0] = {den[0]!r}: the leading coefficient must be non-zero"
                )
            if all(c == 0.0 for c in num):
                raise ControllerError(f"{w}num = {list(num)!r}: the controller does nothing")
            if len(den) - 1 > MAX_LTI_ORDER:
                raise ControllerError(
                    f"{w}den: order {len(den) - 1} > {MAX_LTI_ORDER} (reduce the controller)"
                )
            # leading zeros of num do not raise the order: C is proper when deg num <= deg den
            deg_num = len(num) - 1 - next(i for i, c in enumerate(num) if c != 0.0)
            if deg_num > len(den) - 1:
                raise ControllerError(
                    f"{w}num = {list(num)!r}, den = {list(den)!r}: improper (degree of num "
                    f"{deg_num} > degree of den {len(den) - 1}); a controller must be proper"
                )
            object.__setattr__(self, "num", num)
            object.__setattr__(self, "den", den)
            return
        for k in _SS_FIELDS:
            if getattr(self, k) is None:
                raise ControllerError(f"{w}{k}: missing (law 'lti' in state space)")
        A = self.A
        if isinstance(A, np.ndarray):
            A = A.tolist()
        if not isinstance(A, list | tuple):
            raise ControllerError(f"{w}A = {A!r}: must be a list of rows (n x n)")
        n = len(A)
        if n > MAX_LTI_ORDER:
            raise ControllerError(f"{w}A: order {n} > {MAX_LTI_ORDER} (reduce the controller)")
        rows = tuple(_float_vector(w, f"A[{i}]", r) for i, r in enumerate(A))
        for i, r in enumerate(rows):
            if len(r) != n:
                raise ControllerError(
                    f"{w}A[{i}] = {list(r)!r}: {len(r)} entries, A must be square ({n} x {n})"
                )
        vecs = {}
        for k in ("B", "C"):
            v = getattr(self, k)
            if isinstance(v, np.ndarray):
                v = v.reshape(-1)
            vec = _float_vector(w, k, v)
            if len(vec) != n:
                raise ControllerError(
                    f"{w}{k} = {list(vec)!r}: {len(vec)} entries, needs {n} (one per row of A)"
                )
            vecs[k] = vec
        d = self.D
        if isinstance(d, np.ndarray) and d.size == 1:
            d = d.reshape(-1)[0]
        dval = _finite(w, "D", d, -math.inf, math.inf) if is_finite_real(d) else None
        if dval is None:
            raise ControllerError(f"{w}D = {self.D!r}: must be a finite number (SISO)")
        object.__setattr__(self, "A", rows)
        object.__setattr__(self, "B", vecs["B"])
        object.__setattr__(self, "C", vecs["C"])
        object.__setattr__(self, "D", dval)

    def _lti_anti_windup(self, w: str) -> float | None:
        """T_t [s] of an ``"lti"`` law: ``back_calculation_time_s``, or the PI rule for exactly one
        integrator (see the module docstring), None without an integrator or with anti-windup
        off; ControllerError for several integrators without ``back_calculation_time_s``."""
        if not self.anti_windup:
            return None
        if self.back_calculation_time_s is not None:
            return float(self.back_calculation_time_s)
        sys = self.lti()
        A = np.atleast_2d(np.asarray(sys.A, dtype=float))
        n = int(sys.nstates)
        if n == 0:
            return None
        ts = self.sample_period_s
        Ap = A - np.eye(n) if ts else A  # integrators at 0 in both cases
        lam, V = np.linalg.eig(Ap)
        tol = INTEGRATOR_TOL * max(1.0, float(np.linalg.norm(A, 2)))
        at0 = np.flatnonzero(np.abs(lam) <= tol)
        if at0.size == 0:
            return None
        if at0.size > 1:
            raise ControllerError(
                f"{w}law 'lti' with {at0.size} integrators: give back_calculation_time_s [s] (the "
                "back-calculation time constant) or set anti_windup = false"
            )
        v = np.real(V[:, at0[0]])
        lam_l, W = np.linalg.eig(Ap.T)
        wv = np.real(W[:, int(np.argmin(np.abs(lam_l)))])
        wv = wv / float(wv @ v)  # w^T v = 1
        B = np.asarray(sys.B, dtype=float).reshape(-1)
        Cr = np.asarray(sys.C, dtype=float).reshape(-1)
        Dv = float(np.asarray(sys.D, dtype=float).reshape(-1)[0])
        P = np.outer(v, wv)
        residue = float(Cr @ v) * float(wv @ B)  # k_i (continuous) or k_i Ts (discrete)
        # the rest of C at s = 0: D - C A^# B, A^# = (A + v w^T)^-1 - v w^T (group inverse)
        kp = Dv - float(Cr @ (np.linalg.solve(Ap + P, B) - P @ B))
        ki = residue / ts if ts else residue
        if ki == 0.0:
            return None
        return max(kp / ki, MIN_ANTI_WINDUP_TIME_S)

    @property
    def gain_k_r(self) -> float:
        """Law (6)'s gain used [m s/rad]: ``k_r``, or the built-in paper controller's if None."""
        return law6_defaults()[0] if self.k_r is None else float(self.k_r)

    @property
    def offset_x_r0(self) -> float:
        """The output at zero error used [m]: ``x_r0``, or the built-in paper controller's if
        None."""
        return law6_defaults()[1] if self.x_r0 is None else float(self.x_r0)

    def anti_windup_time_s(self) -> float | None:
        """Back-calculation time constant T_t [s] used: ``back_calculation_time_s`` if given; for the
        PI its integral time kp/ki, at least :data:`MIN_ANTI_WINDUP_TIME_S`; for an ``"lti"`` law
        the same rule on its integrator (module docstring). None: law (6) has no state, no
        integrator, or anti-windup is off."""
        if self.law == "paper" or not self.anti_windup:
            return None
        if self.back_calculation_time_s is not None:
            return float(self.back_calculation_time_s)
        if self.law == "lti":
            return self._lti_anti_windup(f"controller {self.name!r}: ")
        assert self.kp is not None and self.ki is not None
        if self.ki == 0.0:
            return None
        return max(self.kp / self.ki, MIN_ANTI_WINDUP_TIME_S)

    def to_dict(self) -> dict[str, Any]:
        """TOML/JSON-ready form (``None`` fields left out; coefficients as lists)."""
        out: dict[str, Any] = {}
        for k, v in asdict(self).items():
            if v is None:
                continue
            if k == "A":
                v = [list(r) for r in v]
            elif isinstance(v, tuple):
                v = list(v)
            out[k] = v
        return out

    def to_toml(self, path: str | Path, *, header: str | None = None) -> Path:
        """Write the spec as a controller file (the module docstring's format) and return the
        path; ``header`` (lines of text) is written first as ``#`` comments. Floats are written
        with ``repr``: ``load_controller(spec.to_toml(p)) == spec``, coefficients bitwise equal."""
        out = Path(path)
        if out.suffix != ".toml":
            raise ControllerError(f"path = {str(path)!r}: a controller file must end in .toml")
        out.parent.mkdir(parents=True, exist_ok=True)
        lines = [] if header is None else header.splitlines()
        lines.append(
            f"drivetrain_ctrl controller {self.name!r} (law {self.law!r}); keys: "
            "drivetrain_ctrl.control.laws"
        )
        text = "".join(f"# {ln}".rstrip() + "\n" for ln in lines)
        out.write_text(text + _toml_dumps(self.to_dict()), encoding="utf-8")
        return out

    def lti(self) -> control.StateSpace:
        """The LTI block from the signed speed error [rad/s] to x_r - x_r0 [m]."""
        ts = self.sample_period_s
        if self.law == "paper":
            k = self.gain_k_r
            return control.ss([], [], [], [[k]], ts) if ts else control.ss([], [], [], [[k]])
        if self.law == "lti":
            return self._lti_ss()
        assert self.kp is not None and self.ki is not None
        if ts is None:
            return control.ss([[0.0]], [[1.0]], [[self.ki]], [[self.kp]])
        # forward-Euler integrator: x[k+1] = x[k] + Ts e[k]
        return control.ss([[1.0]], [[ts]], [[self.ki]], [[self.kp]], ts)

    def _lti_ss(self) -> control.StateSpace:
        """The state space of an ``"lti"`` law: its matrices, or the controllable canonical form
        of ``num/den`` (:func:`scipy.signal.tf2ss`; for a PI ``kp + ki/s`` exactly law ``"pi"``'s
        realisation ``A = 0, B = 1, C = ki, D = kp``, so both integrate the same state)."""
        ts = self.sample_period_s if self.sample_period_s is not None else 0
        if self.num is not None:
            assert self.den is not None
            num = np.trim_zeros(np.array(self.num), "f")  # leading zeros: not the order
            den = np.array(self.den)
            if den.size == 1:  # a static gain: no state
                return control.ss([], [], [], [[num[-1] / den[0]]], ts)
            A, B, C, D = scipy.signal.tf2ss(num, den)
            return control.ss(A, B, C, D, ts)
        assert self.A is not None and self.B is not None and self.C is not None
        assert self.D is not None
        n = len(self.A)
        A = np.array(self.A, dtype=float).reshape(n, n)
        B = np.array(self.B, dtype=float).reshape(n, 1)
        C = np.array(self.C, dtype=float).reshape(1, n)
        return control.ss(A, B, C, [[float(self.D)]], ts)

    def check_stability(self, params: DrivetrainParams) -> tuple[bool, list[complex]]:
        """Closed-loop poles of the slip-mode loop (:func:`slip_loop`) at x_c = x_r0; returns
        ``(stable, poles)`` and warns :class:`UnstableLoopWarning` if unstable (on every call).
        The simulation still runs: the warning only says what to expect.

        The poles are kept for the last :data:`STABILITY_CACHE_SIZE` keys of what the loop
        depends on (this spec; of ``params`` the clutch capacity slope at x_r0, ``J_1``, ``b_1``
        and the actuator's ``omega_a``, ``delta_a``), so a batch that builds the same controller
        on the same values again (a study's scenarios, parameters the loop does not read) finds
        them instead of rebuilding the loop."""
        key = _stability_key(self, params)
        hit = None if key is None else _STABILITY_CACHE.get(key)
        if hit is None:
            hit = _slip_loop_poles(self, params)
            if key is not None:
                _STABILITY_CACHE[key] = hit
                while len(_STABILITY_CACHE) > STABILITY_CACHE_SIZE:
                    del _STABILITY_CACHE[next(iter(_STABILITY_CACHE))]
        disc, ps = hit
        poles = list(ps)
        if disc:
            stable = all(abs(p) < 1.0 for p in poles)
        else:
            stable = all(p.real < 0.0 for p in poles)
        if not stable:
            worst = max(poles, key=lambda p: abs(p) if disc else p.real)
            warnings.warn(
                f"controller {self.name!r}: the slip-mode loop is unstable at x_c = x_r0 "
                f"(closed-loop pole {worst:.4g}); the simulation runs, expect oscillation or "
                "divergence of the engine speed",
                UnstableLoopWarning,
                stacklevel=2,
            )
        return stable, poles

    def build(
        self,
        params: DrivetrainParams,
        *,
        reference: Signal,
        start_time: float | None = None,
        engine_state: str = "omega_engine",
        driven_state: str = "omega_primary",
    ) -> Controller:
        """The :class:`Controller` for parameter set ``params`` and engine-speed reference
        ``reference`` (omega_r(t) [rad/s]), active from ``start_time`` [s] (None: from the start).
        ``x_r0`` must lie within the actuator stroke ``[actuator.x_min, actuator.x_max]`` of
        ``params`` (else :class:`ControllerError`).
        """
        if not isinstance(reference, Signal):
            raise ControllerError(
                f"controller {self.name!r}: reference = {reference!r}: must be a Signal "
                "(omega_r(t) [rad/s], e.g. signals.constant(167.6))"
            )
        if start_time is not None and not is_finite_real(start_time):
            raise ControllerError(
                f"controller {self.name!r}: start_time = {start_time!r}: must be a finite "
                "number [s] or None"
            )
        act = params.actuator
        x_r0 = self.offset_x_r0
        msg = act.outside_stroke("x_r0", x_r0)
        if msg:
            raise ControllerError(
                f"controller {self.name!r}: {msg} of parameter set {params.name!r}"
            )
        self.check_stability(params)
        latch = LatchRamp("clutch", "stuck", self.engage_rate_m_s, _engaged_position(params))
        rate = None
        if self.rate_limit_m_s is not None:
            # a first-order follower of bandwidth 10 omega_a, limited to the rate
            rate = (self.rate_limit_m_s, 10.0 * act.omega_a)
        return Controller(
            name=self.name,
            lti=self.lti(),
            measurement=((1.0, "ref"), (-1.0, engine_state)),
            output="pedal",
            reference=reference,
            delay_samples=int(self.delay_samples),
            sign_of=(engine_state, driven_state),
            offset=x_r0,
            saturation=(act.x_min, act.x_max),
            latch=latch,
            rate_limit=rate,
            actuator=Actuator(act.omega_a, act.delta_a),
            start_time=start_time,
            anti_windup_time=self.anti_windup_time_s(),
        )


def _float_vector(w: str, name: str, v: Any) -> tuple[float, ...]:
    """``v`` (list, tuple or 1-d array of finite real numbers) as a tuple of floats, else
    ControllerError naming ``w + name`` and the entry."""
    if isinstance(v, np.ndarray):
        if v.ndim != 1:
            raise ControllerError(f"{w}{name} = {v!r}: must be a list of numbers")
        v = v.tolist()
    if not isinstance(v, list | tuple):
        raise ControllerError(f"{w}{name} = {v!r}: must be a list of numbers")
    return tuple(_finite(w, f"{name}[{i}]", c, -math.inf, math.inf) for i, c in enumerate(v))


def _toml_value(where: str, v: Any) -> Any:
    """``v`` in a form TOML writes and reads back equal (and JSON can hold): tables with string
    keys, lists, str, bool, int, float (not NaN); NumPy scalars and arrays and tuples converted.
    Anything else (None, dates, objects) is a ControllerError naming the key."""
    if isinstance(v, dict):
        out = {}
        for k, x in v.items():
            if not isinstance(k, str):
                raise ControllerError(f"{where}: key {k!r}: keys must be strings")
            out[k] = _toml_value(f"{where}.{k}", x)
        return out
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, list | tuple):
        return [_toml_value(f"{where}[{i}]", x) for i, x in enumerate(v)]
    if isinstance(v, bool | np.bool_):
        return bool(v)
    if isinstance(v, int | np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        if math.isnan(float(v)):
            raise ControllerError(f"{where} = nan: leave an undefined value out")
        return float(v)
    if isinstance(v, str):
        return v
    raise ControllerError(
        f"{where} = {v!r}: must be a table, list, string, number or bool (kept in TOML and in the "
        "reports' JSON; TOML has no null: leave the key out)"
    )


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k)


def _toml_inline(v: Any) -> str:
    """One TOML value on one line (numbers with ``repr``: they read back bitwise equal)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)  # 'inf', '-inf', '1e-05', '-0.0': all TOML floats
    if isinstance(v, str):
        # JSON's escapes are TOML's basic-string escapes; TOML also escapes DEL
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, list):
        return "[" + ", ".join(_toml_inline(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_inline(x)}" for k, x in v.items()) + "}"
    raise ControllerError(f"{v!r}: not a TOML value")


def _toml_dumps(d: dict[str, Any], prefix: str = "") -> str:
    """TOML text of ``d`` (values as :func:`_toml_value` leaves them): scalars and arrays one per
    line (an array of arrays one row per line), then the sub-tables under their headers.
    ``tomllib.loads(_toml_dumps(d)) == d``."""
    lines = []
    tables = []
    for k, v in d.items():
        if isinstance(v, dict):
            tables.append((k, v))
        elif isinstance(v, list) and v and all(isinstance(x, list) for x in v):
            rows = "".join(f"    {_toml_inline(x)},\n" for x in v)
            lines.append(f"{_toml_key(k)} = [\n{rows}]")
        else:
            lines.append(f"{_toml_key(k)} = {_toml_inline(v)}")
    text = "".join(ln + "\n" for ln in lines)
    for k, v in tables:
        name = f"{prefix}{_toml_key(k)}"
        # a table holding only tables needs no header of its own (its sub-tables define it)
        only_tables = bool(v) and all(isinstance(x, dict) for x in v.values())
        head = "" if only_tables else f"\n[{name}]\n"
        text += head + _toml_dumps(v, prefix=f"{name}.")
    return text


def _engaged_position(params: DrivetrainParams) -> float:
    """x_c [m] of full engagement: the first knot of the clutch element's capacity table."""
    table = clutch_friction(params).capacity_table
    assert table is not None
    return float(table.x[0])


#: how many slip-loop stability checks :meth:`ControllerSpec.check_stability` keeps
STABILITY_CACHE_SIZE: int = 256
_STABILITY_CACHE: dict[Any, tuple[bool, tuple[complex, ...]]] = {}


def _stability_key(spec: ControllerSpec, params: DrivetrainParams) -> Any:
    """What :func:`slip_loop` reads (the spec; of ``params``: the clutch capacity slope at x_r0,
    J_1, b_1, omega_a, delta_a), hashable; None if the spec cannot be hashed."""
    act = params.actuator
    slope = abs(clutch_friction(params).capacity_slope(spec.offset_x_r0, side="right"))
    key = (spec, slope, params.engine.J1, params.engine.b1, act.omega_a, act.delta_a)
    try:
        hash(key)
    except TypeError:
        return None
    return key


def _slip_loop_poles(
    spec: ControllerSpec, params: DrivetrainParams
) -> tuple[bool, tuple[complex, ...]]:
    """``(sampled, closed-loop poles)`` of :func:`slip_loop` in negative feedback (the poles of
    ``feedback(L, 1)``). A continuous loop's characteristic polynomial ``den_L + num_L`` is
    formed from the polynomials of :func:`slip_loop` (the products python-control forms) with
    numpy, without building transfer-function objects (a study checks every sample's loop)."""
    if spec.sample_period_s is not None:
        L = slip_loop(spec, params)
        ps = tuple(complex(p) for p in np.atleast_1d(control.poles(control.feedback(L, 1))))
        return True, ps
    num_p, den_p = _slip_plant_polys(spec, params)
    num_c, den_c = _controller_polys(spec)
    num = np.polymul(num_p, num_c)
    den = np.polymul(den_p, den_c)
    return False, tuple(complex(p) for p in np.atleast_1d(np.roots(np.polyadd(den, num))))


def _slip_plant_polys(
    spec: ControllerSpec, params: DrivetrainParams
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator of :func:`slip_loop`'s plant ``|k13'(x_r0)| A(s)/(J_1 s + b_1)``
    (:func:`law6_loop_closed_form` with unit gain)."""
    return _law6_loop_polys(**_slip_plant_args(spec, params))


def _slip_plant_args(spec: ControllerSpec, params: DrivetrainParams) -> dict[str, Any]:
    """The arguments of law (6)'s loop with unit gain that make :func:`slip_loop`'s plant:
    ``k13'(x_r0)`` the clutch element's capacity slope (at a knot, the piece towards opening),
    a constant friction coefficient, the engine's ``J_1`` and ``b_1`` and the actuator."""
    slope = abs(clutch_friction(params).capacity_slope(spec.offset_x_r0, side="right"))
    act = params.actuator
    return {
        "k_r": 1.0,
        "dk13_dxc": slope,
        "mu": 1.0,
        "J1": params.engine.J1,
        "b1_eff": params.engine.b1,
        "actuator": Actuator(act.omega_a, act.delta_a),
    }


def _controller_polys(spec: ControllerSpec) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator of ``control.tf(spec.lti())``, kept per (hashable) spec."""
    try:
        return _controller_polys_cached(spec)
    except TypeError:  # an unhashable spec
        return _controller_polys_of(spec)


def _controller_polys_of(spec: ControllerSpec) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    C = control.tf(spec.lti())
    return np.asarray(C.num[0][0], dtype=float), np.asarray(C.den[0][0], dtype=float)


_controller_polys_cached = functools.lru_cache(maxsize=64)(_controller_polys_of)


def slip_loop(spec: ControllerSpec, params: DrivetrainParams) -> control.TransferFunction:
    """Loop gain of ``spec`` in slip with a constant friction coefficient, at x_c = x_r0.

    ``L = C(s) |k13'(x_r0)| A(s) / (J_1 s + b_1)``: controller LTI block ``C`` [m s/rad], clutch
    capacity slope ``k13' = dk13/dx_c`` [N m/m] (eq. (5); the clutch element's
    ``capacity_slope``), actuator ``A`` [-], engine inertia ``J_1`` [kg m^2] and viscous friction
    ``b_1`` [N m s/rad] (the Coulomb part of the engine friction is constant in slip and does not
    enter). The same on both sign branches of law (6): the sign switch and the sign of the
    clutch torque cancel. Sampled controllers: the plant is discretised with a zero-order hold at
    the sample period and the transport delay is ``z^-d``. A first check used by :meth:`build`;
    the linear-analysis module gives the full picture (slip-dependent mu, driveline coupling).
    """

    # the plant |k13'| A(s) / (J_1 s + b_1): law (6)'s loop with unit gain, the controller apart
    plant = law6_loop_closed_form(**_slip_plant_args(spec, params))
    C = control.tf(spec.lti())
    ts = spec.sample_period_s
    if ts is None:
        return control.tf(control.series(C, plant))
    pd = control.c2d(plant, ts, method="zoh")
    delay = control.tf([1.0], [1.0] + [0.0] * spec.delay_samples, ts)
    return control.tf(control.series(C, pd, delay))


#: the order the built-in controllers are listed (and the demo runs them) in; a file in
#: ``control/builtin/`` not named here follows, alphabetically
BUILTIN_ORDER: tuple[str, ...] = ("paper", "pi", "paper-10ms", "pi-10ms", "robust-pi", "hinf")

#: the package whose ``builtin/`` folder holds the built-in controller files
_PACKAGE = __name__.rpartition(".")[0]


@functools.cache
def _builtin_specs() -> tuple[ControllerSpec, ...]:
    specs = []
    for stem, f in builtin_files(_PACKAGE, order=BUILTIN_ORDER).items():
        spec = load_toml_as(f, controller_from_dict, error=ControllerError)
        if spec.name != stem:
            raise ControllerError(f"{f}: name = {spec.name!r}: must be the file's stem {stem!r}")
        specs.append(spec)
    return tuple(specs)


def builtin_controllers() -> dict[str, ControllerSpec]:
    """The built-in controllers by name: the TOML files in ``control/builtin/`` (package data; see
    the module docstring)."""
    return {s.name: s for s in _builtin_specs()}


@functools.cache
def law6_defaults() -> tuple[float, float]:
    """``(k_r [m s/rad], x_r0 [m])`` of the built-in ``paper`` controller (the paper's Section IV):
    the values a spec that leaves ``k_r`` or ``x_r0`` out uses. Read from ``paper.toml`` itself,
    so the file is the one place these numbers are written."""
    f = builtin_files(_PACKAGE)["paper"]
    d = read_toml(f, error=ControllerError)
    for key in ("k_r", "x_r0"):
        if not is_finite_real(d.get(key)):
            raise ControllerError(f"{f}: {key} = {d.get(key)!r}: must be a finite number")
    return float(d["k_r"]), float(d["x_r0"])


#: the keys of a controller file: the fields of :class:`ControllerSpec`
_KEYS = frozenset(f.name for f in fields(ControllerSpec))


def controller_from_dict(d: dict[str, Any], *, where: str = "") -> ControllerSpec:
    """A :class:`ControllerSpec` from its TOML form; unknown keys are errors naming the key."""
    reject_unknown(where, set(d), _KEYS, error=ControllerError)
    if "law" not in d:
        raise ControllerError(f"{where}law: missing (one of {LAWS})")
    return ControllerSpec(**{"name": "controller", **d})


def save_controller(spec: ControllerSpec, path: str | Path, *, header: str | None = None) -> Path:
    """Write ``spec`` to the controller file ``path`` (:meth:`ControllerSpec.to_toml`)."""
    if not isinstance(spec, ControllerSpec):
        raise ControllerError(f"spec = {spec!r}: must be a ControllerSpec")
    return spec.to_toml(path, header=header)


def spec_from_lti(
    sys: control.LTI,
    *,
    name: str,
    form: str = "tf",
    x_r0: float | None = None,
    delay_samples: int = 0,
    design: dict[str, Any] | None = None,
    **options: Any,
) -> ControllerSpec:
    """An ``"lti"`` :class:`ControllerSpec` with the SISO python-control system ``sys`` (from the
    error [rad/s] to x_r - x_r0 [m]; continuous, or discrete with ``sys.dt`` [s] > 0 as the sample
    period) as its LTI block.

    ``form``: ``"tf"`` writes ``num``/``den`` (python-control's ``tf(sys)``), ``"ss"`` the
    matrices of ``ss(sys)``. ``x_r0`` [m], ``delay_samples``, ``design`` (provenance table) and
    the other keyword ``options`` (``engage_rate_m_s``, ``rate_limit_m_s``, ``anti_windup``,
    ``back_calculation_time_s``) are the spec's fields; unknown ones are errors naming the key.
    """
    if not isinstance(sys, control.LTI):
        raise ControllerError(f"sys = {sys!r}: must be a python-control LTI system")
    if sys.ninputs != 1 or sys.noutputs != 1:
        raise ControllerError(
            f"sys: must be SISO, got {sys.ninputs} inputs and {sys.noutputs} outputs"
        )
    allowed = {"engage_rate_m_s", "rate_limit_m_s", "anti_windup", "back_calculation_time_s"}
    reject_unknown("spec_from_lti: ", set(options), allowed, error=ControllerError)
    dt = sys.dt
    if dt is True:
        raise ControllerError("sys.dt = True: give the sample period [s] of a discrete system")
    ts = float(dt) if dt else None
    coef: dict[str, Any]
    if form == "tf":
        tf = control.tf(sys)
        coef = {
            "num": tuple(float(c) for c in np.atleast_1d(tf.num[0][0])),
            "den": tuple(float(c) for c in np.atleast_1d(tf.den[0][0])),
        }
    elif form == "ss":
        ss = control.ss(sys)
        n = int(ss.nstates)
        coef = {
            "A": tuple(tuple(float(c) for c in r) for r in np.asarray(ss.A).reshape(n, n)),
            "B": tuple(float(c) for c in np.asarray(ss.B).reshape(-1)),
            "C": tuple(float(c) for c in np.asarray(ss.C).reshape(-1)),
            "D": float(np.asarray(ss.D).reshape(-1)[0]),
        }
    else:
        raise ControllerError(f"form = {form!r}: 'tf' (num/den) or 'ss' (A, B, C, D)")
    return ControllerSpec(
        name=name,
        law="lti",
        x_r0=x_r0,
        sample_period_s=ts,
        delay_samples=delay_samples,
        design=design,
        **coef,
        **options,
    )


def load_controller(source: str | Path | ControllerSpec) -> ControllerSpec:
    """A built-in controller by name, a controller TOML file, or a spec (returned as is)."""
    if isinstance(source, ControllerSpec):
        return source
    if not isinstance(source, str | Path):
        raise ControllerError(
            f"controller = {source!r}: give a built-in name, a .toml path or a ControllerSpec"
        )
    b = builtin_controllers()
    return load_builtin_or_toml(
        source, b, controller_from_dict, what="controller", error=ControllerError
    )


def law6_controller(
    params: DrivetrainParams,
    *,
    reference: Signal,
    engine_state: str = "omega_engine",
    driven_state: str = "omega_primary",
    engage_rate: float | None = 0.05,
    start_time: float | None = None,
) -> Controller:
    """The paper's law (6): ``x_r = x_r0 + k_r (omega_r - omega_1) sgn(omega_1 - omega_3)``.

    ``reference`` is omega_r(t) [rad/s]; x_r0, k_r the paper's (:func:`law6_defaults`); the
    actuator from ``params.actuator`` with the stroke as saturation. When the clutch locks, the
    pedal is ramped at ``engage_rate`` [m/s] (> 0) to fully engaged (``None``: no latch). A
    shortcut for ``ControllerSpec(name="law6", law="paper").build(...)``.
    """
    return _from_spec(
        "law6_controller",
        params,
        dict(name="law6", law="paper"),
        reference=reference,
        engage_rate=engage_rate,
        start_time=start_time,
        engine_state=engine_state,
        driven_state=driven_state,
    )


def _from_spec(
    fn: str,
    params: DrivetrainParams,
    fields: dict[str, Any],
    *,
    reference: Signal,
    engage_rate: float | None,
    start_time: float | None,
    engine_state: str,
    driven_state: str,
) -> Controller:
    """Build the :class:`~drivetrain_ctrl.control.laws.ControllerSpec` of a shortcut; its errors
    name the shortcut's argument (``engage_rate``, ``dt``) beside the spec's field."""

    if engage_rate is not None:
        fields = {**fields, "engage_rate_m_s": engage_rate}
    try:
        spec = ControllerSpec(**fields)
    except ControllerError as exc:
        msg = str(exc)
        for arg, field_name in (("dt", "sample_period_s"), ("engage_rate", "engage_rate_m_s")):
            msg = msg.replace(field_name, f"{arg} ({field_name})")
        raise ValueError(f"{fn}: {msg}") from None
    c = spec.build(
        params,
        reference=reference,
        start_time=start_time,
        engine_state=engine_state,
        driven_state=driven_state,
    )
    return c if engage_rate is not None else replace(c, latch=None)


def pi_controller(
    params: DrivetrainParams,
    *,
    reference: Signal,
    kp: float,
    ki: float,
    dt: float | None = None,
    delay_samples: int = 0,
    engine_state: str = "omega_engine",
    driven_state: str = "omega_primary",
    engage_rate: float | None = 0.05,
    start_time: float | None = None,
) -> Controller:
    """A PI variant of law (6): ``x_r = x_r0 + sgn(w1 - w3) (kp e + ki int e)``, ``e = w_r - w_1``,
    with back-calculation anti-windup; continuous, or sampled every ``dt`` [s] (forward-Euler
    integrator) with ``delay_samples``; the latch as in :func:`law6_controller`. A shortcut for
    ``ControllerSpec(law="pi", ...).build``.
    """
    return _from_spec(
        "pi_controller",
        params,
        dict(
            name="pi",
            law="pi",
            kp=kp,
            ki=ki,
            sample_period_s=dt,
            delay_samples=delay_samples,
        ),
        reference=reference,
        engage_rate=engage_rate,
        start_time=start_time,
        engine_state=engine_state,
        driven_state=driven_state,
    )


def law6_loop_closed_form(
    *, k_r: float, dk13_dxc: float, mu: float, J1: float, b1_eff: float, actuator: Actuator
) -> control.TransferFunction:
    """Closed form of law (6)'s loop with constant mu:
    ``L(s) = k_r |k13'(x_c)| mu A(s) / (J_1 s + b_1')`` (units: k_r [m s/rad], k13' [N m/m],
    J_1 [kg m^2], b_1' [N m s/rad]; L dimensionless). TypeError if ``actuator`` is not an
    :class:`~drivetrain_ctrl.control.blocks.Actuator`."""
    num, den = _law6_loop_polys(
        k_r=k_r, dk13_dxc=dk13_dxc, mu=mu, J1=J1, b1_eff=b1_eff, actuator=actuator
    )
    return control.tf(num, den)


def _law6_loop_polys(
    *, k_r: float, dk13_dxc: float, mu: float, J1: float, b1_eff: float, actuator: Actuator
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator of :func:`law6_loop_closed_form` (the same checks)."""
    if not isinstance(actuator, Actuator):
        raise TypeError(f"actuator: an Actuator is needed, got {type(actuator).__name__}")
    kr, j1 = positive_float("k_r", k_r), positive_float("J1", J1)
    g = kr * abs(finite_float("dk13_dxc", dk13_dxc)) * finite_float("mu", mu)
    act = actuator_tf(actuator)
    num = np.polymul([g], act.num[0][0])
    den = np.polymul([j1, finite_float("b1_eff", b1_eff)], act.den[0][0])
    return num, den
