"""Building blocks of a drivetrain: bodies joined in a chain by couplings (POG form).

A *chain* is a row of rigid bodies ``0 .. n-1`` (rotational: inertia [kg m^2], speed [rad/s];
translational: mass [kg], speed [m/s]). Coupling ``c`` joins body ``c`` (upstream) and body
``c + 1`` (downstream) through a ratio ``r_c`` (a gear ratio, or ``1/R`` for a wheel of radius
``R``: the POG connection block). Its relative speed, in the upstream frame, is

    w_c = omega_c - r_c * omega_{c+1}

and its torque ``T_c`` (upstream frame) acts as ``-T_c`` on body ``c`` and ``+r_c T_c`` on body
``c + 1``, so the power it takes is ``T_c w_c``. ``T_c`` is the parallel sum of an optional
spring (linear or odd piecewise-linear table, optionally with a backlash gap), a viscous damper
and a friction element. Each body may also have viscous, quadratic (aerodynamic) and Coulomb
friction to ground, a constant load (e.g. gravity on a slope), an external torque input, and a
first-order lagged source (the engine).

These are pure data (frozen dataclasses). :func:`drivetrain_ctrl.plant.model.Model` compiles a
:class:`Chain` into arrays for the compiled kernels and offers the mode, guard, energy and
linearisation API. The drivetrain itself (:mod:`drivetrain_ctrl.plant.drivetrain`) is built from these
blocks.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import overload

import numpy as np
from numpy.typing import NDArray

from ..core.tables import PwlTable, _pwl_clamped
from ..core.validate import (
    check_finite,
    check_name,
    check_sequence,
    check_type,
    is_real,
    store_knots,
)

__all__ = [
    "PwlTable",
    "Spring",
    "Friction",
    "Body",
    "Coupling",
    "LaggedSource",
    "Chain",
    "FRICTION_MODES",
    "BACKLASH_MODES",
]

#: default mode names of a friction element, in kernel code order (0, 1, 2, 3)
FRICTION_MODES: tuple[str, str, str, str] = ("stuck", "slip+", "slip-", "open")
#: mode names of a spring with backlash: negative contact, gap, positive contact
BACKLASH_MODES: tuple[str, str, str] = ("contact-", "gap", "contact+")


@dataclass(frozen=True, slots=True)
class Spring:
    """Odd piecewise-linear spring with an optional backlash gap.

    ``x`` (>= 0, starting at 0, strictly increasing) and ``y`` (starting at 0) give the torque
    [N m] (or force [N]) at deflection ``x`` [rad] (or [m]) for positive deflections; negative
    deflections mirror it (odd). Beyond the last knot the last segment's slope continues.
    ``backlash`` is the half gap ``g`` >= 0: the spring acts on ``q - g`` for ``q > g``, on
    ``q + g`` for ``q < -g`` and carries nothing in between. With a gap, the regions are the modes
    ``contact-``, ``gap``, ``contact+``.
    """

    x: tuple[float, ...]
    y: tuple[float, ...]
    backlash: float = 0.0
    name: str = "spring"

    def __post_init__(self) -> None:
        store_knots(self, self.name)
        if len(self.x) != len(self.y) or len(self.x) < 2:
            raise ValueError(f"{self.name}: needs at least two knots (x, y) of equal length")
        check_finite(self.name, "x[0]", self.x[0])
        check_finite(self.name, "y[0]", self.y[0])
        if self.x[0] != 0.0 or self.y[0] != 0.0:
            raise ValueError(
                f"{self.name}: first knot must be (0, 0), got ({self.x[0]}, {self.y[0]})"
            )
        for i in range(1, len(self.x)):
            check_finite(self.name, f"x[{i}]", self.x[i])
            check_finite(self.name, f"y[{i}]", self.y[i])
            if not self.x[i] > self.x[i - 1]:
                raise ValueError(
                    f"{self.name}: x must be strictly increasing at x[{i}]={self.x[i]}"
                )
        check_finite(self.name, "backlash", self.backlash, lo=0.0)

    @classmethod
    def linear(cls, stiffness: float, *, backlash: float = 0.0, name: str = "spring") -> Spring:
        """Linear spring of ``stiffness`` [N m/rad or N/m] with half gap ``backlash``."""
        check_finite(name, "stiffness", stiffness, lo=0.0, strict=True)
        check_finite(name, "backlash", backlash, lo=0.0)
        return cls((0.0, 1.0), (0.0, float(stiffness)), float(backlash), name)

    def torque(self, q: float) -> float:
        """Spring torque [N m] at deflection ``q`` [rad] (reference implementation)."""
        a = abs(q) - self.backlash
        if a <= 0.0:
            return 0.0
        x, y = self.x, self.y
        k = len(x) - 2
        for j in range(len(x) - 1):
            if a <= x[j + 1]:
                k = j
                break
        val = y[k] + (y[k + 1] - y[k]) * (a - x[k]) / (x[k + 1] - x[k])
        return val if q > 0 else -val


@dataclass(frozen=True, slots=True)
class Friction:
    """Coulomb friction element (between two bodies, or from a body to ground).

    Kinetic capacity [N m or N] = ``scale * base * mu(|w|)`` where ``base`` is ``1`` if
    ``capacity_input`` is None, the input's value if ``capacity_table`` is None, else
    ``capacity_table(input)``; ``mu`` is ``mu_table(|w|)`` (ratio, 1 at zero slip) or 1.
    Static capacity = ``static_ratio * scale * base``. A capacity <= 0 is the mode ``open``: no
    torque and no stick test. ``mode_names`` rename the modes (stuck, slip+, slip-, open), e.g.
    ``grip`` for a tyre.
    """

    scale: float = 1.0
    capacity_input: str | None = None
    capacity_table: PwlTable | None = None
    static_ratio: float = 1.0
    mu_table: PwlTable | None = None
    mode_names: tuple[str, str, str, str] = FRICTION_MODES
    name: str = "friction"

    def __post_init__(self) -> None:
        check_name("Friction", "name", self.name)
        check_finite(self.name, "scale", self.scale, lo=0.0)
        check_finite(self.name, "static_ratio", self.static_ratio, lo=1.0)
        if self.capacity_input is not None:
            check_name(self.name, "capacity_input", self.capacity_input)
        check_type(self.name, "capacity_table", self.capacity_table, PwlTable)
        check_type(self.name, "mu_table", self.mu_table, PwlTable)
        if self.capacity_table is not None and self.capacity_input is None:
            raise ValueError(f"{self.name}: capacity_table needs a capacity_input")
        if self.mu_table is not None:
            if self.mu_table.x[0] != 0.0:
                raise ValueError(
                    f"{self.name}: mu_table must start at slip 0, got {self.mu_table.x[0]}"
                )
            if self.mu_table.y[0] != 1.0 or min(self.mu_table.y) < 0.0:
                raise ValueError(
                    f"{self.name}: mu_table.y = {self.mu_table.y!r}: a friction ratio is 1 at "
                    "zero slip and never negative"
                )
        if (
            not isinstance(self.mode_names, (tuple, list))
            or len(self.mode_names) != 4
            or not all(isinstance(n, str) and n.strip() for n in self.mode_names)
            or len(set(self.mode_names)) != 4
        ):
            raise ValueError(
                f"{self.name}: mode_names = {self.mode_names!r}: must be 4 distinct non-empty "
                "names (stuck, slip+, slip-, open)"
            )

    @overload
    def capacity(self, v: float, region: int | None = None) -> float: ...
    @overload
    def capacity(
        self, v: NDArray[np.float64], region: int | None = None
    ) -> NDArray[np.float64]: ...
    def capacity(
        self, v: float | NDArray[np.float64], region: int | None = None
    ) -> float | NDArray[np.float64]:
        """Kinetic capacity at zero slip [N m or N] with the capacity input at ``v`` (its unit).

        ``scale * base`` with ``base`` = 1 (no ``capacity_input``), ``v`` (no table) or
        ``capacity_table(v)``, the table evaluated as the kernels do: ``slope_r v + offset_r``
        on its region ``r`` (0 below the first knot, ``k`` between knots ``k-1`` and ``k``, a
        knot in the piece on its left; clamped beyond the ends). ``region`` imposes ``r`` (the
        region a :class:`~drivetrain_ctrl.plant.model.Mode` holds); None takes the region of
        ``v``. For the car's clutch this is the transmissible torque k12(x_c) of eq. (1) (k13(x_c)
        of the reduced model, eq. (5) and Fig. 12): ``k12_max * pedal_map(x_c)`` [N m] of the
        pedal position x_c [m]. An array ``v`` (with ``region`` None) gives an array.
        """
        if self.capacity_input is None:
            return float(self.scale * 1.0) if np.ndim(v) == 0 else np.full(np.shape(v), self.scale)
        if self.capacity_table is None:
            if np.ndim(v) == 0:
                return float(self.scale * float(v))
            return np.asarray(self.scale * np.asarray(v, dtype=np.float64))
        bounds, slopes, offs = _pwl_clamped(self.capacity_table)
        if np.ndim(v) == 0:
            r = bisect.bisect_left(bounds, float(v)) if region is None else int(region)
            return float(self.scale * (slopes[r] * float(v) + offs[r]))
        a = np.asarray(v, dtype=np.float64)
        ri = np.searchsorted(np.asarray(bounds), a, side="left") if region is None else region
        s_arr, o_arr = np.asarray(slopes), np.asarray(offs)
        return np.asarray(self.scale * (s_arr[ri] * a + o_arr[ri]))

    def capacity_slope(self, v: float, side: str = "right") -> float:
        """Slope d capacity / d v [N m or N per unit of the input] of :meth:`capacity` at ``v``.

        0 without a capacity input, ``scale`` without a table; with a table, ``scale`` times the
        slope of its piece at ``v``: at a knot the piece on ``side`` (``"right"`` or ``"left"``),
        beyond the knots the end piece (the gain of the map next to its end, where the clamped
        table itself is flat). For the car's clutch: k12'(x_c) = dk13/dx_c [N m/m] (eq. (5)), the
        gain from pedal position to clutch torque in slip.
        """
        if side not in ("right", "left"):
            raise ValueError(f"{self.name}: side = {side!r}: must be 'right' or 'left'")
        if self.capacity_input is None:
            return 0.0
        t = self.capacity_table
        if t is None:
            return float(self.scale)
        if len(t.x) == 1:
            return 0.0
        x = float(v)
        k = (bisect.bisect_right if side == "right" else bisect.bisect_left)(t.x, x) - 1
        k = min(max(k, 0), len(t.x) - 2)
        return float(self.scale * ((t.y[k + 1] - t.y[k]) / (t.x[k + 1] - t.x[k])))


@dataclass(frozen=True, slots=True)
class Body:
    """A rigid body of a chain.

    ``inertia`` [kg m^2] (rotational) or mass [kg] (translational); ``viscous`` [N m s/rad or
    N s/m] to ground; ``quadratic`` [N m s^2/rad^2 or N s^2/m^2] drag ``quadratic * w |w|``;
    ``load`` constant torque/force [N m or N] acting on the body (gravity on a slope: negative
    uphill), stored as potential energy via the body's position; ``ground_friction`` Coulomb
    friction to ground; ``torque_input`` name of an input whose value times ``input_gain``
    is a torque [N m] / force [N] on the body.
    """

    name: str
    inertia: float
    kind: str = "rotational"
    viscous: float = 0.0
    quadratic: float = 0.0
    load: float = 0.0
    ground_friction: Friction | None = None
    torque_input: str | None = None
    input_gain: float = 1.0

    def __post_init__(self) -> None:
        check_name("Body", "name", self.name)
        check_finite(self.name, "inertia", self.inertia, lo=0.0, strict=True)
        check_type(self.name, "ground_friction", self.ground_friction, Friction)
        if self.torque_input is not None:
            check_name(self.name, "torque_input", self.torque_input)
        check_finite(self.name, "viscous", self.viscous, lo=0.0)
        check_finite(self.name, "quadratic", self.quadratic, lo=0.0)
        check_finite(self.name, "load", self.load)
        check_finite(self.name, "input_gain", self.input_gain)
        if self.kind not in ("rotational", "translational"):
            raise ValueError(f"{self.name}.kind = {self.kind!r}: must be rotational|translational")

    @property
    def tracks_position(self) -> bool:
        """True if the body's position is a state (translational bodies and loaded bodies)."""
        return self.kind == "translational" or self.load != 0.0


@dataclass(frozen=True, slots=True)
class Coupling:
    """Joins body ``c`` and ``c + 1``: ratio, and spring / damper / friction in parallel.

    ``ratio`` [-] (or [1/m] from rotation to translation); ``damper`` [N m s/rad or N s/m] in the
    upstream frame; the spring's stiffness is in the upstream frame too.

    ``damper_in_gap``: where the damper acts when the spring has a backlash gap. True (the
    default; the car paper's model of the gearbox's b34): in every mode, in the gap too, where it
    is the only link between the two bodies. False: only while the spring is in contact (modes
    ``contact-`` and ``contact+``; no torque and no dissipation in the ``gap``), as in Modelica's
    ElastoBacklash, but without its limit of the damper torque to the spring torque: at impact
    the coupling's torque jumps by ``damper * w``, and it may pull while the contact opens.
    False needs a spring with ``backlash > 0``.
    """

    name: str
    ratio: float = 1.0
    spring: Spring | None = None
    damper: float = 0.0
    friction: Friction | None = None
    damper_in_gap: bool = True

    def __post_init__(self) -> None:
        check_name("Coupling", "name", self.name)
        check_finite(self.name, "ratio", self.ratio, lo=0.0, strict=True)
        check_finite(self.name, "damper", self.damper, lo=0.0)
        check_type(self.name, "spring", self.spring, Spring)
        check_type(self.name, "friction", self.friction, Friction)
        check_type(self.name, "damper_in_gap", self.damper_in_gap, bool, optional=False)
        if self.spring is None and self.damper == 0.0 and self.friction is None:
            raise ValueError(f"{self.name}: a coupling needs a spring, a damper or a friction")
        if not self.damper_in_gap and (self.spring is None or self.spring.backlash <= 0.0):
            has = "no spring" if self.spring is None else "a spring without backlash"
            raise ValueError(
                f"{self.name}.damper_in_gap = False: the damper acts only in contact, which needs "
                f"a spring with backlash > 0; the coupling has {has}"
            )


@dataclass(frozen=True, slots=True)
class LaggedSource:
    """A torque source through a first-order lag (the engine of the paper, Section II-A).

    State ``s`` [input unit] with ``tau * s' = input - s``; torque on ``body`` =
    ``gain * s`` or, if ``gain_table`` is given, ``gain_table(omega_body) * s`` [N m].
    """

    name: str
    body: str
    input: str
    tau: float
    gain: float = 1.0
    gain_table: PwlTable | None = None

    def __post_init__(self) -> None:
        check_name("LaggedSource", "name", self.name)
        check_name(self.name, "body", self.body)
        check_name(self.name, "input", self.input)
        check_finite(self.name, "tau", self.tau, lo=0.0, strict=True)
        check_finite(self.name, "gain", self.gain)
        check_type(self.name, "gain_table", self.gain_table, PwlTable)


@dataclass(frozen=True, slots=True)
class Chain:
    """A row of bodies joined by couplings (``len(couplings) == len(bodies) - 1``).

    ``input_units``: optional unit of each input (e.g. ``{"pedal": "m"}``), shown in the column
    names of results; an input without one gets no unit (its unit depends on the gain or scale
    it drives). ``input_ranges``: optional physical range ``(lo, hi)`` of each input (in its
    unit; e.g. ``{"throttle": (0.0, 1.0)}``): the simulator rejects an input signal that leaves
    it; an input without one is unbounded."""

    bodies: tuple[Body, ...]
    couplings: tuple[Coupling, ...]
    sources: tuple[LaggedSource, ...] = ()
    inputs: tuple[str, ...] = ()
    name: str = "chain"
    element_names: dict[str, str] = field(default_factory=dict, compare=False, hash=False)
    input_units: dict[str, str] = field(default_factory=dict, compare=False, hash=False)
    input_ranges: dict[str, tuple[float, float]] = field(
        default_factory=dict, compare=False, hash=False
    )

    def __post_init__(self) -> None:
        for fld, cls in (("bodies", Body), ("couplings", Coupling), ("sources", LaggedSource)):
            seq = getattr(self, fld)
            check_sequence("Chain", fld, seq)
            for i, el in enumerate(seq):
                if not isinstance(el, cls):
                    raise TypeError(f"Chain.{fld}[{i}] = {el!r}: must be a {cls.__name__}")
        check_sequence("Chain", "inputs", self.inputs)
        for i, nm in enumerate(self.inputs):
            check_name("Chain", f"inputs[{i}]", nm)
        if len(set(self.inputs)) != len(self.inputs):
            raise ValueError(f"Chain.inputs = {self.inputs!r}: names must not repeat")
        if len(self.bodies) < 1:
            raise ValueError("Chain needs at least one body")
        if len(self.couplings) != len(self.bodies) - 1:
            raise ValueError(
                f"Chain: {len(self.bodies)} bodies need {len(self.bodies) - 1} couplings, "
                f"got {len(self.couplings)}"
            )
        names = [b.name for b in self.bodies] + [c.name for c in self.couplings]
        if len(set(names)) != len(names):
            raise ValueError(f"Chain: body and coupling names must be unique, got {names}")
        # names that label states (sources) and modes (friction elements, backlashes) must not
        # collide within their kind: each names a result column
        sources = [s.name for s in self.sources]
        moded = [b.ground_friction.name for b in self.bodies if b.ground_friction is not None]
        moded += [c.friction.name for c in self.couplings if c.friction is not None]
        moded += [c.name for c in self.couplings if c.spring is not None and c.spring.backlash]
        for what, labels in (("sources", sources), ("friction elements and backlashes", moded)):
            dup = sorted({n for n in labels if labels.count(n) > 1})
            if dup:
                raise ValueError(
                    f"Chain: the names {dup} are used by more than one of the {what} (each names "
                    "a state or a mode and its result column)"
                )
        body_names = {b.name for b in self.bodies}
        used: list[tuple[str, str | None]] = []
        for b in self.bodies:
            used.append((b.name, b.torque_input))
            if b.ground_friction is not None:
                used.append((b.name, b.ground_friction.capacity_input))
        for c in self.couplings:
            if c.friction is not None:
                used.append((c.name, c.friction.capacity_input))
        for s in self.sources:
            if s.body not in body_names:
                raise ValueError(f"source {s.name}: unknown body {s.body!r}; bodies: {body_names}")
            used.append((s.name, s.input))
        if not isinstance(self.input_units, Mapping):
            raise TypeError(
                f"Chain.input_units = {self.input_units!r}: must be a mapping input name -> unit"
            )
        for iname, unit in self.input_units.items():
            if iname not in self.inputs:
                raise ValueError(
                    f"Chain.input_units: {iname!r} is not declared in Chain.inputs {self.inputs}"
                )
            if not isinstance(unit, str):
                raise TypeError(f"Chain.input_units[{iname!r}] = {unit!r}: must be a str")
        if not isinstance(self.input_ranges, Mapping):
            raise TypeError(
                f"Chain.input_ranges = {self.input_ranges!r}: must be a mapping input name -> "
                "(lo, hi)"
            )
        for iname, rng in self.input_ranges.items():
            if iname not in self.inputs:
                raise ValueError(
                    f"Chain.input_ranges: {iname!r} is not declared in Chain.inputs {self.inputs}"
                )
            ok = isinstance(rng, (tuple, list)) and len(rng) == 2
            ok = ok and all(is_real(v) and not math.isnan(float(v)) for v in rng)
            if not ok or not float(rng[0]) < float(rng[1]):
                raise ValueError(
                    f"Chain.input_ranges[{iname!r}] = {rng!r}: must be (lo, hi) with lo < hi"
                )
        for owner, inp in used:
            if inp is not None and inp not in self.inputs:
                raise ValueError(
                    f"{owner}: input {inp!r} is not declared in Chain.inputs {self.inputs}"
                )

    def body_index(self, name: str) -> int:
        """Index of the body called ``name``."""
        for i, b in enumerate(self.bodies):
            if b.name == name:
                return i
        raise KeyError(f"no body {name!r}; bodies: {[b.name for b in self.bodies]}")


def two_body_clutch(
    j1: float, j2: float, *, capacity: float | str, static_ratio: float = 1.0, load2: float = 0.0
) -> Chain:
    """Small example chain: two inertias [kg m^2] joined by a clutch.

    ``capacity`` is a constant [N m] or the name of an input giving it.
    """
    if isinstance(capacity, str):
        if capacity == "torque1":
            raise ValueError("capacity = 'torque1': that is the drive torque's input; name another")
        fr = Friction(capacity_input=capacity, static_ratio=static_ratio, name="clutch")
        inputs: Sequence[str] = (capacity, "torque1")
    else:
        check_finite("two_body_clutch", "capacity", capacity, lo=0.0)
        fr = Friction(scale=float(capacity), static_ratio=static_ratio, name="clutch")
        inputs = ("torque1",)
    return Chain(
        bodies=(Body("b1", j1, torque_input="torque1"), Body("b2", j2, load=load2)),
        couplings=(Coupling("clutch", friction=fr),),
        inputs=tuple(inputs),
        name="two-body clutch",
    )
