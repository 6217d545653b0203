"""The car drivetrain of the paper (Section II) and its reduced model (Section III), as chains.

Full model (:func:`full_chain`), bodies in order, each in its own frame:

====  =============  ===========================================================  =========
#     body           contents                                                     frame
====  =============  ===========================================================  =========
0     ``engine``     J1; viscous b1, Coulomb c1 to ground (stall); lagged source  engine
1     ``disc``       J2 (clutch disc, damper input); viscous b2                   primary
2     ``primary``    J3 (primary shaft, gearbox input); viscous b3                primary
3     ``secondary``  J4 (secondary shaft + differential); viscous b4              secondary
4     ``hub``        (1 - tread_fraction) J5 (wheels, hubs); viscous b5; brake    wheel
5     ``tread``      tread_fraction J5 (tyre tread ring)                          wheel
6     ``vehicle``    M_v; b_v, aerodynamic drag, rolling resistance, slope        vehicle
====  =============  ===========================================================  =========

Couplings: ``clutch`` (engine-disc, friction k12(x_c) mu(slip)), ``damper`` (disc-primary, spring
phi_e and friction k23), ``backlash`` (primary-secondary, ratio tau_r, teeth spring h34 with
backlash g34 and damper b34, primary frame; b34 acts in the gap too unless
``gearbox.backlash_damping`` is ``"contact"``), ``axle`` (secondary-hub, ratio D_c, h45/b45
referred to the secondary shaft), ``tyre_hub`` (hub-tread, h56/b56), ``tyre`` (tread-vehicle,
ratio 1/R_p, Coulomb limit k_w R_p: modes grip / slip+ / slip-).

Engine friction is counted once: ``C_1 = C_G - b_1(omega_1)`` with ``b_1(omega) = b1 omega + c1
sgn(omega)`` (so B = diag(0, b2, b3) in eq. (2)). ``C_G = K theta_f`` (paper) or
``C_max(omega_1) theta_f`` with ``tau_p theta_f' = theta - theta_f``.

The tyre/hub compliance h56 needs a body on its far side to grip or slip: the tread ring, a
fraction ``tread_fraction`` of J5 (the paper's J5 is the total, so J25 is unchanged).

Inputs (SI): ``throttle`` theta [-] in [0, 1], ``pedal`` x_c [m] (larger = clutch more open),
``brake`` service-brake capacity [N m] at the wheels.

Reduced model (:func:`reduced_chain`, Section III): bodies ``engine`` (J1), ``primary`` (J25, the
disc, primary shaft, secondary shaft and wheels rigidly joined, primary frame) and ``vehicle``
(M_v); couplings ``clutch`` (k13 = k12) and ``backlash`` (the equivalent shaft: ratio tau_t / R_p, stiffness h_t with
backlash g_t and damping b_t, primary frame). Damping of the equivalent shaft: for Kelvin-Voigt
elements in series the compliance adds, ``1/(h_t + j w b_t) = sum 1/(h_i + j w b_i)``; to first
order in frequency this gives

    b_t = h_t^2 * (b34 / h34^2 + tau_t^2 * (b45 / h45^2 + b56 / h56^2))

(all referred to the primary shaft). With ``gearbox.backlash_damping = "contact"`` the lumped
damper b_t acts only in contact too: in the gap the series chain (gap, h45/b45, h56/b56) carries
the torque of its gap link, which is then zero, so the equivalent shaft carries none either (with
``"always"`` the gap link carries b34 w, and the paper's reduced model keeps the whole b_t there).
The tyre block is *not* kept: the reduction lumps the wheels into J25 (J5 rigid), so there is no
wheel inertia left for the tyre to slip against; the reduced model assumes grip
(:func:`tyre_force_margin` tells how far a trajectory is from the limit).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..core.tables import PwlTable
from ..core.units import GRAVITY
from ..core.validate import is_finite_real
from .chain import Body, Chain, Coupling, Friction, LaggedSource, Spring
from .model import Model
from .params import ClutchParams, DrivetrainParams

__all__ = [
    "Drivetrain",
    "INPUTS",
    "clutch_friction",
    "full_chain",
    "input_ranges",
    "reduced_chain",
    "full_model",
    "reduced_model",
    "ReducedFigures",
    "reduced_figures",
]

INPUTS: tuple[str, str, str] = ("throttle", "pedal", "brake")
#: units of the inputs: throttle fraction, clutch pedal (release bearing) travel, brake torque
INPUT_UNITS: dict[str, str] = {"throttle": "-", "pedal": "m", "brake": "N m"}


def _table(t: PwlTable, name: str) -> PwlTable:
    """A parameter map's knots as a chain element's table ``name``: clamped, no symmetry (the
    elements evaluate mu(slip) at |slip| themselves), no labels."""
    return PwlTable(t.x, t.y, name)


def _check_gear(p: DrivetrainParams, gear: int) -> None:
    if not isinstance(p, DrivetrainParams):
        raise TypeError(f"params = {p!r}: must be a DrivetrainParams (e.g. default_params())")
    n = len(p.gearbox.gear_ratios)
    if isinstance(gear, bool) or not isinstance(gear, (int, np.integer)) or not 1 <= gear <= n:
        raise ValueError(f"gear = {gear!r}: must be an integer in 1..{n}")


def _check_slope(slope: float) -> float:
    if not is_finite_real(slope):
        raise ValueError(f"slope = {slope!r} rad: must be a finite number")
    s = float(slope)
    if abs(s) >= math.pi / 2:
        raise ValueError(f"slope = {slope!r} rad: must be finite and within (-pi/2, pi/2)")
    return s


def _engine(p: DrivetrainParams) -> tuple[Body, LaggedSource]:
    e = p.engine
    body = Body(
        "engine",
        e.J1,
        viscous=e.b1,
        ground_friction=Friction(
            scale=e.c1,
            static_ratio=e.static_ratio,
            mode_names=("standstill", "turning+", "turning-", "free"),
            name="engine",
        )
        if e.c1 > 0
        else None,
    )
    if e.torque_model == "map":
        assert e.full_load_curve is not None  # EngineParams requires it with torque_model "map"
        src = LaggedSource(
            "engine", "engine", "throttle", e.tau_p, 1.0, _table(e.full_load_curve, "C_max")
        )
    else:
        src = LaggedSource("engine", "engine", "throttle", e.tau_p, e.K)
    return body, src


def clutch_friction(p: DrivetrainParams) -> Friction:
    """The clutch's friction element: capacity k12(x_c) = ``clutch.k12_max * clutch.pedal_map(x_c)``
    [N m] of the ``pedal`` input x_c [m] (paper, eq. (1); k13(x_c) in eq. (5), Fig. 12), times
    ``mu_table(|slip|)``. The element's table holds the products ``k12_max * shape`` (N m at the
    knots; its ``scale`` is 1); :meth:`Friction.capacity` evaluates it and
    :meth:`Friction.capacity_slope` gives k12'(x_c) [N m/m]."""
    if not isinstance(p, DrivetrainParams):
        raise TypeError(f"params = {p!r}: must be a DrivetrainParams (e.g. default_params())")
    try:
        return _clutch_friction_kept(p.clutch)
    except TypeError:  # clutch parameters that cannot be hashed: built afresh
        return _clutch_friction(p.clutch)


def _clutch_friction(c: ClutchParams) -> Friction:
    """:func:`clutch_friction` of the clutch parameters ``c`` (immutable, as its result)."""
    k12 = PwlTable(
        tuple(float(v) for v in c.pedal_map.x),
        tuple(c.k12_max * float(v) for v in c.pedal_map.y),
        "pedal_map",
    )
    return Friction(
        scale=1.0,
        capacity_input="pedal",
        capacity_table=k12,
        static_ratio=c.static_ratio,
        mu_table=_table(c.mu_table, "mu_table") if len(c.mu_table.x) > 1 else None,
        mode_names=("stuck", "slip+", "slip-", "open"),
        name="clutch",
    )


#: the clutch element of the last few clutch parameter sets (a study row builds its drivetrain
#: and checks its controller with the same clutch)
_clutch_friction_kept = functools.lru_cache(maxsize=32)(_clutch_friction)


def _vehicle(p: DrivetrainParams, slope: float) -> Body:
    v = p.vehicle
    return Body(
        "vehicle",
        v.M_v,
        kind="translational",
        viscous=v.b_v,
        quadratic=0.5 * v.rho_a * v.C_x * v.S,
        load=-v.M_v * GRAVITY * math.sin(slope),
        ground_friction=Friction(
            scale=float(v.k_v(slope)),
            static_ratio=v.rolling_static_ratio,
            mode_names=("standstill", "moving+", "moving-", "free"),
            name="vehicle",
        )
        if float(v.k_v(slope)) > 0
        else None,
    )


def input_ranges(p: DrivetrainParams) -> dict[str, tuple[float, float]]:
    """Physical range of each input: throttle theta in [0, 1] [-], pedal (actuator position
    x_c) within the stroke ``[actuator.x_min, actuator.x_max]`` [m], brake capacity in
    ``[0, brake.capacity_max]`` [N m at the wheels]."""
    if not isinstance(p, DrivetrainParams):
        raise TypeError(f"input_ranges: p = {p!r}: must be a DrivetrainParams")
    return {
        "throttle": (0.0, 1.0),
        "pedal": (p.actuator.x_min, p.actuator.x_max),
        "brake": (0.0, p.brake.capacity_max),
    }


def _damper_in_gap(p: DrivetrainParams, gap: float) -> bool:
    """``Coupling.damper_in_gap`` of the ``backlash`` coupling (full model: b34; reduced model:
    the lumped b_t) from ``gearbox.backlash_damping``; with no gap (``g34_wheel = 0``) the two
    choices are the same model, and the coupling has no gap to be off in."""
    return p.gearbox.backlash_damping == "always" or gap == 0.0


def full_chain(p: DrivetrainParams, *, gear: int = 1, slope: float = 0.0) -> Chain:
    """The full drivetrain of Section II as a :class:`Chain` (slope [rad], positive uphill)."""
    _check_gear(p, gear)
    slope = _check_slope(slope)
    tau_r = p.gearbox.tau_r(gear)
    Dc = p.gearbox.D_c
    dl = p.driveline
    eng, src = _engine(p)
    d = p.damper
    spring_x = tuple(float(v) for v in d.spring.x)
    spring_y = tuple(float(v) for v in d.spring.y)
    bodies = (
        eng,
        Body("disc", p.clutch.J2, viscous=p.clutch.b2),
        Body("primary", d.J3, viscous=d.b3),
        Body("secondary", p.gearbox.J4, viscous=p.gearbox.b4),
        Body(
            "hub",
            (1.0 - dl.tread_fraction) * dl.J5,
            viscous=dl.b5,
            ground_friction=Friction(
                scale=1.0,
                capacity_input="brake",
                static_ratio=p.brake.static_ratio,
                mode_names=("holding", "slip+", "slip-", "released"),
                name="brake",
            ),
        ),
        Body("tread", dl.tread_fraction * dl.J5),
        _vehicle(p, slope),
    )
    couplings = (
        Coupling("clutch", friction=clutch_friction(p)),
        Coupling(
            "damper",
            spring=Spring(spring_x, spring_y, 0.0, "phi_e"),
            friction=Friction(scale=d.k23, static_ratio=d.static_ratio, name="damper_friction")
            if d.k23 > 0
            else None,
        ),
        Coupling(
            "backlash",
            ratio=tau_r,
            spring=Spring.linear(p.gearbox.h34, backlash=p.gearbox.g34_primary(gear), name="h34"),
            damper=p.gearbox.b34,
            damper_in_gap=_damper_in_gap(p, p.gearbox.g34_primary(gear)),
        ),
        Coupling(
            "axle",
            ratio=Dc,
            spring=Spring.linear(dl.h45 / Dc**2, name="h45"),
            damper=dl.b45 / Dc**2,
        ),
        Coupling("tyre_hub", spring=Spring.linear(dl.h56, name="h56"), damper=dl.b56),
        Coupling(
            "tyre",
            ratio=1.0 / dl.R_p,
            friction=Friction(
                scale=float(p.vehicle.k_w(slope)) * dl.R_p,
                static_ratio=p.vehicle.tyre_static_ratio,
                mode_names=("grip", "slip+", "slip-", "lifted"),
                name="tyre",
            ),
        ),
    )
    return Chain(
        bodies,
        couplings,
        (src,),
        INPUTS,
        name=f"full drivetrain, gear {gear}",
        input_units=dict(INPUT_UNITS),
        input_ranges=input_ranges(p),
    )


@dataclass(frozen=True, slots=True)
class ReducedFigures:
    """Figures of the reduced model (Section III), primary-shaft frame."""

    J25: float  # [kg m^2]
    h_t: float  # [N m/rad]
    g_t: float  # [rad]
    tau_t: float  # [-]
    b_t: float  # [N m s/rad]


def reduced_figures(p: DrivetrainParams, gear: int = 1) -> ReducedFigures:
    """J25, h_t, g_t, tau_t (paper, Section III) and b_t (formula in the module docstring)."""
    _check_gear(p, gear)
    g = p.gearbox
    dl = p.driveline
    tau_r = g.tau_r(gear)
    tau_t = tau_r * g.D_c
    J25 = p.clutch.J2 + p.damper.J3 + g.J4 / tau_r**2 + dl.J5 / tau_t**2
    h4556 = dl.h45 * dl.h56 / (dl.h45 + dl.h56)
    h_t = 1.0 / (1.0 / g.h34 + tau_t**2 / h4556)
    b_t = h_t**2 * (g.b34 / g.h34**2 + tau_t**2 * (dl.b45 / dl.h45**2 + dl.b56 / dl.h56**2))
    return ReducedFigures(J25=J25, h_t=h_t, g_t=g.g34_primary(gear), tau_t=tau_t, b_t=b_t)


def reduced_chain(p: DrivetrainParams, *, gear: int = 1, slope: float = 0.0) -> Chain:
    """The reduced model of Section III as a :class:`Chain` (tyre assumed gripping)."""
    _check_gear(p, gear)
    slope = _check_slope(slope)
    fig = reduced_figures(p, gear)
    g = p.gearbox
    dl = p.driveline
    tau_r = g.tau_r(gear)
    eng, src = _engine(p)
    visc = p.clutch.b2 + p.damper.b3 + g.b4 / tau_r**2 + dl.b5 / fig.tau_t**2
    bodies = (
        eng,
        Body(
            "primary",
            fig.J25,
            viscous=visc,
            ground_friction=Friction(
                scale=1.0 / fig.tau_t,
                capacity_input="brake",
                static_ratio=p.brake.static_ratio,
                mode_names=("holding", "slip+", "slip-", "released"),
                name="brake",
            ),
        ),
        _vehicle(p, slope),
    )
    couplings = (
        Coupling("clutch", friction=clutch_friction(p)),
        Coupling(
            "backlash",
            ratio=fig.tau_t / dl.R_p,
            spring=Spring.linear(fig.h_t, backlash=fig.g_t, name="h_t"),
            damper=fig.b_t,
            damper_in_gap=_damper_in_gap(p, fig.g_t),
        ),
    )
    return Chain(
        bodies,
        couplings,
        (src,),
        INPUTS,
        name=f"reduced drivetrain, gear {gear}",
        input_units=dict(INPUT_UNITS),
        input_ranges=input_ranges(p),
    )


class Drivetrain:
    """A drivetrain model: the compiled :class:`Model` plus what it was built from.

    ``kind`` is ``"full"`` or ``"reduced"``; ``gear`` 1-based; ``slope`` [rad].
    """

    __slots__ = ("model", "params", "gear", "slope", "kind")
    model: Model
    params: DrivetrainParams
    gear: int
    slope: float
    kind: str

    def __init__(
        self, params: DrivetrainParams, *, kind: str = "full", gear: int = 1, slope: float = 0.0
    ):
        if kind not in ("full", "reduced"):
            raise ValueError(f"kind = {kind!r}: must be 'full' or 'reduced'")
        chain = (full_chain if kind == "full" else reduced_chain)(params, gear=gear, slope=slope)
        object.__setattr__(self, "model", Model(chain))
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "gear", int(gear))
        object.__setattr__(self, "slope", float(slope))
        object.__setattr__(self, "kind", kind)

    def __setattr__(self, key: str, value: object) -> None:
        raise AttributeError(f"Drivetrain is immutable; cannot set {key!r}")

    def __delattr__(self, key: str) -> None:
        raise AttributeError(f"Drivetrain is immutable; cannot delete {key!r}")

    def clutch_capacity(self, x_c: float) -> float:
        """The clutch's transmissible torque k12(x_c) [N m] at pedal position ``x_c`` [m], zero
        slip (paper, eq. (1); k13(x_c) of eq. (5), Fig. 12): ``k12_max * pedal_map(x_c)``, read
        from the model's clutch element (:meth:`Friction.capacity`)."""
        return self.model.friction("clutch").capacity(float(x_c))

    def clutch_capacity_slope(self, x_c: float, side: str = "right") -> float:
        """dk12/dx_c [N m/m] at ``x_c`` [m] (negative: opening lowers the capacity), at a knot of
        the pedal map the piece on ``side`` (:meth:`Friction.capacity_slope`)."""
        return self.model.friction("clutch").capacity_slope(float(x_c), side)

    @property
    def tau_t(self) -> float:
        """Total ratio tau_r * D_c [-] of the engaged gear."""
        return float(self.params.gearbox.tau_t(self.gear))

    def vehicle_speed_to_primary(self, v: float) -> float:
        """Primary-shaft speed [rad/s] that matches vehicle speed ``v`` [m/s] with no slip."""
        try:
            va = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            va = np.asarray(np.nan)
        if isinstance(v, (bool, np.bool_, str)) or not np.isfinite(va).all():
            raise ValueError(f"v = {v!r} [m/s]: must be a finite number (or an array of them)")
        out = va * self.tau_t / self.params.driveline.R_p
        return float(out) if out.ndim == 0 else out  # type: ignore[return-value]

    def rigid_state(
        self,
        *,
        omega_engine: float,
        v_vehicle: float,
        throttle: float = 0.0,
        twist_torque: float = 0.0,
    ) -> NDArray[np.float64]:
        """A state with every shaft turning at the speed of the vehicle (no slip) except the
        engine at ``omega_engine`` [rad/s], springs preloaded to ``twist_torque`` [N m, primary
        frame] (negative: coasting, backlash in negative contact), engine lag at ``throttle``
        (in [0, 1])."""
        for nm, v in (
            ("omega_engine", omega_engine),
            ("v_vehicle", v_vehicle),
            ("throttle", throttle),
            ("twist_torque", twist_torque),
        ):
            if not is_finite_real(v):
                raise ValueError(f"rigid_state: {nm} = {v!r}: must be a finite number")
        if not 0.0 <= throttle <= 1.0:
            raise ValueError(f"rigid_state: throttle = {throttle!r}: must lie in [0, 1]")
        m = self.model
        x = np.zeros(m.nx)
        R = self.params.driveline.R_p
        w_prim = self.vehicle_speed_to_primary(v_vehicle)
        speeds = {
            "omega_engine": omega_engine,
            "omega_disc": w_prim,
            "omega_primary": w_prim,
            "omega_secondary": w_prim / self.params.gearbox.tau_r(self.gear),
            "omega_hub": v_vehicle / R,
            "omega_tread": v_vehicle / R,
            "v_vehicle": v_vehicle,
        }
        for name, val in speeds.items():
            if name in m.state_names:
                x[m.state_index(name)] = val
        # spring twists carrying twist_torque (primary frame) through the chain
        for c, cp in enumerate(m.chain.couplings):
            if cp.spring is None:
                continue
            # torque in this coupling's (upstream) frame: primary torque times the ratios above it
            T = twist_torque * math.prod(cc.ratio for cc in m.chain.couplings[:c])
            x[m.state_index(f"q_{cp.name}")] = _spring_inverse(cp.spring, T)
        x[m.state_index("lag_engine")] = throttle
        return x


def _spring_inverse(sp: Spring, T: float) -> float:
    """Deflection at which spring ``sp`` carries torque ``T`` (0 -> middle of the gap)."""
    if T == 0.0:
        return 0.0
    a = abs(T)
    xs, ys = sp.x, sp.y
    for k in range(len(xs) - 1):
        if a <= ys[k + 1] or k == len(xs) - 2:
            s = (ys[k + 1] - ys[k]) / (xs[k + 1] - xs[k])
            d = xs[k] + (a - ys[k]) / s
            return math.copysign(sp.backlash + d, T)
    raise AssertionError("unreachable")  # pragma: no cover


def full_model(params: DrivetrainParams, *, gear: int = 1, slope: float = 0.0) -> Drivetrain:
    """The full drivetrain (Section II) for ``gear`` on a road of ``slope`` [rad]."""
    return Drivetrain(params, kind="full", gear=gear, slope=slope)


def reduced_model(params: DrivetrainParams, *, gear: int = 1, slope: float = 0.0) -> Drivetrain:
    """The reduced drivetrain (Section III) for ``gear`` on a road of ``slope`` [rad]."""
    return Drivetrain(params, kind="reduced", gear=gear, slope=slope)
