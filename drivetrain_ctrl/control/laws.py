"""Clutch start controllers by name or from a TOML file: law (6) and its PI variant.

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
    law = "pi"                 # "paper" (law 6) or "pi"
    k_r = 3.0e-4               # [m s/rad] paper law gain (default: the built-in paper's)
    x_r0 = 0.07                # [m] output at zero error (default: the built-in paper's)
    kp = 3.0e-4                # [m s/rad] PI proportional gain
    ki = 1.5e-3                # [m/rad] PI integral gain
    sample_period_s = 0.01     # optional: sampled controller
    delay_samples = 1          # transport delay in samples (sampled only)
    engage_rate_m_s = 0.05     # latch ramp rate after lock-up
    rate_limit_m_s = 0.5       # optional actuator rate limit
    anti_windup = true

Law (6)'s gains are controller settings, not plant parameters: a spec that leaves ``k_r`` or
``x_r0`` out takes the built-in ``paper`` controller's value (:func:`law6_defaults`, read from
``control/builtin/paper.toml``). ``x_r0`` must lie within the actuator stroke of the parameter set
the controller is built for (checked by :meth:`ControllerSpec.build`).
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import control
import numpy as np

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
    "LAWS",
    "GAIN_RANGE",
]

#: control laws a spec can name
LAWS: tuple[str, ...] = ("paper", "pi")

#: accepted magnitude of a gain [m s/rad or m/rad]; beyond it the value is surely a unit error
GAIN_RANGE: tuple[float, float] = (0.0, 1.0)

#: (min, max) of the sample period [s]
SAMPLE_PERIOD_RANGE: tuple[float, float] = (1e-5, 0.5)

#: smallest back-calculation time constant [s] of the PI anti-windup
MIN_ANTI_WINDUP_TIME_S: float = 0.01

#: largest transport delay [samples]
MAX_DELAY_SAMPLES: int = 100


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
    ``engage_rate_m_s``, ``rate_limit_m_s`` [m/s]. ``None`` for ``k_r``/``x_r0`` takes the built-in
    ``paper`` controller's values (:func:`law6_defaults`); :attr:`gain_k_r`, :attr:`offset_x_r0`
    are the values used.
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
            raise ControllerError(f"{w}kp/ki are PI gains; law {self.law!r} uses k_r")
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
        """Back-calculation time constant T_t [s] of the PI: its integral time kp/ki, at least
        :data:`MIN_ANTI_WINDUP_TIME_S` (None: law (6) has no state, or anti-windup is off)."""
        if self.law != "pi" or not self.anti_windup:
            return None
        assert self.kp is not None and self.ki is not None
        if self.ki == 0.0:
            return None
        return max(self.kp / self.ki, MIN_ANTI_WINDUP_TIME_S)

    def to_dict(self) -> dict[str, Any]:
        """TOML/JSON-ready form (``None`` fields left out)."""
        return {k: v for k, v in asdict(self).items() if v is not None}

    def lti(self) -> control.StateSpace:
        """The LTI block from the signed speed error [rad/s] to x_r - x_r0 [m]."""
        ts = self.sample_period_s
        if self.law == "paper":
            k = self.gain_k_r
            return control.ss([], [], [], [[k]], ts) if ts else control.ss([], [], [], [[k]])
        assert self.kp is not None and self.ki is not None
        if ts is None:
            return control.ss([[0.0]], [[1.0]], [[self.ki]], [[self.kp]])
        # forward-Euler integrator: x[k+1] = x[k] + Ts e[k]
        return control.ss([[1.0]], [[ts]], [[self.ki]], [[self.kp]], ts)

    def check_stability(self, params: DrivetrainParams) -> tuple[bool, list[complex]]:
        """Closed-loop poles of the slip-mode loop (:func:`slip_loop`) at x_c = x_r0; returns
        ``(stable, poles)`` and warns :class:`UnstableLoopWarning` if unstable. The simulation
        still runs: the warning only says what to expect."""
        L = slip_loop(self, params)
        poles = [complex(p) for p in np.atleast_1d(control.poles(control.feedback(L, 1)))]
        if L.isdtime(strict=True):
            stable = all(abs(p) < 1.0 for p in poles)
        else:
            stable = all(p.real < 0.0 for p in poles)
        if not stable:
            worst = max(poles, key=lambda p: abs(p) if L.isdtime(strict=True) else p.real)
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


def _engaged_position(params: DrivetrainParams) -> float:
    """x_c [m] of full engagement: the first knot of the clutch element's capacity table."""
    table = clutch_friction(params).capacity_table
    assert table is not None
    return float(table.x[0])


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

    x0 = spec.offset_x_r0
    # k13'(x_r0): the clutch element's capacity slope (at a knot, the piece towards opening)
    slope = abs(clutch_friction(params).capacity_slope(x0, side="right"))
    act = params.actuator
    # the plant |k13'| A(s) / (J_1 s + b_1): law (6)'s loop with unit gain, the controller apart
    plant = law6_loop_closed_form(
        k_r=1.0,
        dk13_dxc=slope,
        mu=1.0,
        J1=params.engine.J1,
        b1_eff=params.engine.b1,
        actuator=Actuator(act.omega_a, act.delta_a),
    )
    C = control.tf(spec.lti())
    ts = spec.sample_period_s
    if ts is None:
        return control.tf(control.series(C, plant))
    pd = control.c2d(plant, ts, method="zoh")
    delay = control.tf([1.0], [1.0] + [0.0] * spec.delay_samples, ts)
    return control.tf(control.series(C, pd, delay))


#: the order the built-in controllers are listed (and the demo runs them) in; a file in
#: ``control/builtin/`` not named here follows, alphabetically
BUILTIN_ORDER: tuple[str, ...] = ("paper", "pi", "paper-10ms", "pi-10ms")

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
    if not isinstance(actuator, Actuator):
        raise TypeError(f"actuator: an Actuator is needed, got {type(actuator).__name__}")
    kr, j1 = positive_float("k_r", k_r), positive_float("J1", J1)
    g = kr * abs(finite_float("dk13_dxc", dk13_dxc)) * finite_float("mu", mu)
    return control.tf([g], [j1, finite_float("b1_eff", b1_eff)]) * actuator_tf(actuator)
