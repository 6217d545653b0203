"""Immutable, validated parameters of the dry-clutch drivetrain model.

The parameters follow the symbols of Zanasi, Grossi et al., "Dynamic Modeling and Control of a Car
Transmission System"; every value is in SI units (m, kg, s, rad, N, N m). Each field of each
section carries metadata (see :func:`field_info`):

``unit``
    SI unit of the stored value, e.g. ``"kg m^2"``; ``"-"`` for dimensionless values.
``frame``
    The shaft (or body) the value is referred to: ``"engine"`` (omega_1), ``"primary"`` (clutch disc
    and gearbox primary shaft, omega_2 / omega_3), ``"secondary"`` (gearbox secondary shaft,
    omega_sec = omega_3 / tau_r), ``"wheel"`` (half-shafts and wheels, omega_4 / omega_5),
    ``"vehicle"`` (translation, v_v) or ``"-"`` (not tied to a shaft).
``description``, ``min``, ``max``, ``min_inclusive``, ``max_inclusive``
    Meaning and admissible range (``None`` = unbounded).

Objects are frozen, slotted dataclasses validated on construction; an invalid value raises
:class:`~drivetrain_ctrl.core.validate.ParameterError` (a :class:`ValueError`, re-exported here)
whose message names the dotted field path and the offending value, e.g. ``engine.J1 = -0.2: must
be > 0 [kg m^2]``. Derive modified sets with
:meth:`DrivetrainParams.replace` (dotted paths), which validates again.

Parameter files (TOML) have a ``[meta]`` table (``name``, ``description``), one table per section
(``[engine]``, ``[clutch]``, ``[damper]``, ``[gearbox]``, ``[driveline]``, ``[vehicle]``,
``[brake]``, ``[actuator]``) and an optional ``[provenance]`` table mapping quoted
dotted field paths to source texts. Lookup tables are written
``name = { x = [...], y = [...] }``. Every field is required, with no silent defaults, except
those whose default is the paper's own choice:

* every static/kinetic friction ratio (``engine.static_ratio``, ``clutch.static_ratio``,
  ``damper.static_ratio``, ``vehicle.rolling_static_ratio``, ``vehicle.tyre_static_ratio``,
  ``brake.static_ratio``): 1.0, the paper's single ``k sgn()`` value;
* ``clutch.mu_table``: flat, mu(slip)/mu(0) = 1 at every slip speed;
* ``driveline.b5``: 0.0 (no viscous loss at the wheels);
* ``gearbox.backlash_damping``: ``"always"``, the paper's mesh damping b34 in parallel with the
  dead-zone spring, acting in the backlash gap too (``"contact"``: only while the teeth touch);
* ``engine.full_load_curve`` may be omitted when ``engine.torque_model = "linear"`` (the paper's
  ``C_G = K theta``); it is required when ``torque_model = "map"``.

The clutch capacity (the paper's k12(x_c), eq. (1), and k13(x_c), eq. (5) and Fig. 12) is
``k12(x_c) = clutch.k12_max * pedal_map(x_c)`` [N m]: ``k12_max`` is the fully engaged capacity and
``pedal_map`` its shape, k12/k12_max [-] in [0, 1] versus the release position x_c [m], 1 at its
first knot (fully engaged), non-increasing. A ``pedal_map`` written in N m (any value above 1, the
older form of the file) is read as that capacity: its largest value must equal ``k12_max`` (to a
relative 1e-9, else :class:`ParameterError`) and it is stored divided by ``k12_max``, so the
capacity is the file's values again (exactly when they are ``k12_max`` times binary fractions, as
in the built-in set; else to one rounding). :func:`save_params` writes the shape.

A file may say only what differs from another set: a top-level ``base = "passenger-car"`` (a
built-in set name, or a path to a TOML file, relative to the file that names it) loads that set
and overrides it with the file's own values, section by section and key by key (a table is
replaced whole). The result is validated like a whole set. The file must give its own
``[meta] name``; the base's provenance entries of the values it overrides are dropped (they
describe the base's values), its own are added. Example::

    base = "passenger-car"

    [meta]
    name = "heavy passenger car"

    [vehicle]
    M_v = 1600.0

Unknown or misspelt keys are errors (with a "did you mean" suggestion). The one exception is a
``[law6]`` section (with ``[provenance]`` entries ``"law6.*"``) of older files: law (6)'s gains are
controller settings (``k_r``, ``x_r0`` of a controller file, :mod:`drivetrain_ctrl.control.laws`),
so the section is read, ignored and reported with a :class:`ParameterSectionWarning` naming it and
its values (a plant parameter set cannot set a controller's gains).
"""

from __future__ import annotations

import dataclasses
import functools
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar, NamedTuple, TypeAlias, cast

import numpy as np
import tomli_w
from numpy.typing import NDArray

from ..core.registry import load_toml_as, read_toml
from ..core.tables import PwlTable
from ..core.units import GRAVITY
from ..core.validate import ParameterError, did_you_mean, real_number

__all__ = [
    "FRAMES",
    "ActuatorParams",
    "BrakeParams",
    "ClutchParams",
    "DamperParams",
    "DrivelineParams",
    "DrivetrainParams",
    "EngineParams",
    "GearboxParams",
    "ParameterError",
    "ParameterSectionWarning",
    "Table",
    "VehicleParams",
    "available_parameter_sets",
    "default_params",
    "field_info",
    "field_paths",
    "load_params",
    "params_from_dict",
    "params_to_dict",
    "save_params",
]

#: Admissible values of the ``frame`` metadata entry.
FRAMES: tuple[str, ...] = ("engine", "primary", "secondary", "wheel", "vehicle", "-")

PARAMETER_SETS_DIR: Path = Path(__file__).resolve().parent / "parameter_sets"

FloatOrArray: TypeAlias = float | NDArray[np.float64]


class ParameterSectionWarning(FutureWarning):
    """A parameter file has a section that is no longer part of the plant's schema (``[law6]``:
    law (6)'s gains are controller settings); it is ignored. A :class:`FutureWarning`, so it is
    shown by default to users of scripts and of the command line."""


#: sections of older parameter files that are read and ignored, with the place their values
#: belong now (named in the :class:`ParameterSectionWarning`)
RETIRED_SECTIONS: dict[str, str] = {
    "law6": (
        "law (6)'s gains are controller settings, not plant parameters: give them as k_r "
        '[m s/rad] and x_r0 [m] in a controller file (law = "paper"; the built-in "paper" '
        "controller has the paper's 3e-4 and 0.07)"
    ),
}


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------


def _fmt(value: object) -> str:
    """Format an offending value for an error message."""
    if isinstance(value, bool | np.bool_):
        return repr(bool(value))
    if isinstance(value, int | float | np.integer | np.floating):
        try:
            return f"{float(value):.12g}"
        except OverflowError:
            return repr(value)
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _to_float(path: str, value: object, md: Mapping[str, Any] | None = None) -> float:
    """A finite real number as a ``float`` (:func:`~drivetrain_ctrl.core.validate.real_number`),
    within the field's bounds if ``md`` (its metadata) is given; ParameterError otherwise."""
    if md is None:
        return real_number(path, value, error=ParameterError, show=_fmt)
    return real_number(
        path,
        value,
        lo=md["min"],
        hi=md["max"],
        lo_open=not md["min_inclusive"],
        hi_open=not md["max_inclusive"],
        unit=md["unit"],
        error=ParameterError,
        show=_fmt,
    )


def _to_float_tuple(
    path: str, value: object, md: Mapping[str, Any] | None = None
) -> tuple[float, ...]:
    """A 1-D sequence of real numbers as a tuple of finite floats, each checked by
    :func:`_to_float`."""
    if isinstance(value, np.ndarray):
        if value.ndim != 1:
            raise ParameterError(
                f"{path}: must be a 1-D sequence of numbers, got shape {value.shape}"
            )
        value = value.tolist()
    if isinstance(value, str | bytes | Mapping) or not isinstance(value, Sequence):
        raise ParameterError(f"{path} = {_fmt(value)}: must be a sequence of numbers")
    return tuple(_to_float(f"{path}[{i}]", v, md) for i, v in enumerate(value))


# --------------------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------------------

#: ``params.Table`` is the package's one table type, :class:`~drivetrain_ctrl.core.tables.PwlTable`
#: (the older name, kept for files and scripts that import it).
Table = PwlTable


class _TableSpec(NamedTuple):
    """Axis labels and options of a parameter table (keyword arguments of :class:`PwlTable`)."""

    x_name: str
    x_unit: str
    y_name: str
    y_unit: str
    extrapolation: str = "clamp"
    symmetry: str = "none"


_PLAIN_TABLE = _TableSpec("x", "-", "y", "-")
_FULL_LOAD_SPEC = _TableSpec("omega1", "rad/s", "C_max", "N m")
_PEDAL_SPEC = _TableSpec("x_c", "m", "k12/k12_max", "-")
_MU_SPEC = _TableSpec("slip", "rad/s", "mu_ratio", "-", "clamp", "even")
_SPRING_SPEC = _TableSpec("theta_d", "rad", "phi_e", "N m", "linear", "odd")


def _labels(t: PwlTable) -> _TableSpec:
    return _TableSpec(t.x_name, t.x_unit, t.y_name, t.y_unit, t.extrapolation, t.symmetry)


def _coerce_table(path: str, value: object, spec: _TableSpec) -> PwlTable:
    """The field's table (named ``path``, with the field's labels and options) from a table
    (with those labels or none) or a ``{x, y}`` mapping."""
    if isinstance(value, PwlTable):
        labels = _labels(value)
        if labels not in (spec, _PLAIN_TABLE):
            raise ParameterError(
                f"{path}: table is labelled {labels.x_name} [{labels.x_unit}] -> {labels.y_name} "
                f"[{labels.y_unit}] ({labels.extrapolation}, {labels.symmetry}), expected "
                f"{spec.x_name} [{spec.x_unit}] -> {spec.y_name} [{spec.y_unit}] "
                f"({spec.extrapolation}, {spec.symmetry})"
            )
        x: object = value.x
        y: object = value.y
    elif isinstance(value, Mapping):
        for key in value:
            if key not in ("x", "y"):
                raise ParameterError(
                    f"{path}.{key}: unknown key (a table has 'x' = {spec.x_name} [{spec.x_unit}] "
                    f"and 'y' = {spec.y_name} [{spec.y_unit}]){did_you_mean(str(key), ('x', 'y'))}"
                )
        for key in ("x", "y"):
            if key not in value:
                raise ParameterError(f"{path}.{key}: missing table column")
        x, y = value["x"], value["y"]
    else:
        raise ParameterError(
            f"{path} = {_fmt(value)}: must be a table {{ x = [...], y = [...] }} "
            f"({spec.x_name} [{spec.x_unit}] -> {spec.y_name} [{spec.y_unit}])"
        )
    return PwlTable(cast(Any, x), cast(Any, y), path, **spec._asdict())


# --------------------------------------------------------------------------------------------------
# field metadata
# --------------------------------------------------------------------------------------------------

_NO_DEFAULT: Any = dataclasses.MISSING


def _param(
    unit: str,
    frame: str,
    description: str,
    *,
    min: float | None = None,
    max: float | None = None,
    min_inclusive: bool = True,
    max_inclusive: bool = True,
    kind: str = "float",
    table: _TableSpec | None = None,
    choices: tuple[str, ...] | None = None,
    default: Any = _NO_DEFAULT,
) -> Any:
    """A dataclass field with the metadata described in the module docstring."""
    if frame not in FRAMES:
        raise AssertionError(f"bad frame {frame!r}")
    metadata = {
        "unit": unit,
        "frame": frame,
        "description": description,
        "min": min,
        "max": max,
        "min_inclusive": min_inclusive,
        "max_inclusive": max_inclusive,
        "kind": kind,
        "table": table,
        "choices": choices,
        "optional": default is not _NO_DEFAULT,
        "default": None if default is _NO_DEFAULT else default,
    }
    if default is _NO_DEFAULT:
        return field(metadata=metadata)
    return field(default=default, metadata=metadata)


def _static_ratio(what: str) -> Any:
    return _param(
        "-",
        "-",
        f"static/kinetic ratio of the {what} Coulomb friction (breakaway / sliding capacity); "
        "1.0 is the paper's single k sgn() value",
        min=1.0,
        max=3.0,
        default=1.0,
    )


def _coerce_field(path: str, value: object, md: Mapping[str, Any]) -> object:
    kind = md["kind"]
    if kind == "float":
        return _to_float(path, value, md)
    if kind == "floats":
        xs = _to_float_tuple(path, value, md)
        if len(xs) == 0:
            raise ParameterError(f"{path} = []: needs at least one value")
        return xs
    if kind == "choice":
        if value not in md["choices"] or not isinstance(value, str):
            raise ParameterError(
                f"{path} = {_fmt(value)}: must be one of {', '.join(map(repr, md['choices']))}"
                f"{did_you_mean(str(value), md['choices'])}"
            )
        return value
    if kind == "table":
        if value is None and md["optional"]:
            return None
        return _coerce_table(path, value, md["table"])
    raise AssertionError(kind)  # pragma: no cover


class _Section:
    """Base of the parameter sections: coerces and validates every field after ``__init__``."""

    __slots__ = ()
    _section: ClassVar[str] = ""

    def __post_init__(self) -> None:
        for f in fields(cast(Any, self)):
            value = getattr(self, f.name)
            coerced = _coerce_field(f"{self._section}.{f.name}", value, f.metadata)
            if coerced is not value:
                object.__setattr__(self, f.name, coerced)
        self._check()

    def _check(self) -> None:
        """Cross-field checks of the section (overridden)."""


# --------------------------------------------------------------------------------------------------
# sections
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, kw_only=True)
class EngineParams(_Section):
    """Engine: ``C_G = K theta / (1 + tau_p s)``, ``C_1 = C_G - b1 omega1 - c1 sgn(omega1)``."""

    _section: ClassVar[str] = "engine"

    J1: float = _param(
        "kg m^2", "engine", "engine + flywheel inertia", min=0.0, min_inclusive=False
    )
    K: float = _param(
        "N m",
        "engine",
        "generated torque per unit throttle theta in [0, 1] (torque_model 'linear')",
        min=0.0,
        min_inclusive=False,
    )
    tau_p: float = _param(
        "s", "-", "time constant of the first-order engine lag", min=0.0, min_inclusive=False
    )
    b1: float = _param(
        "N m s/rad", "engine", "viscous engine friction (linear part of b1(omega1))", min=0.0
    )
    c1: float = _param(
        "N m", "engine", "Coulomb engine friction (constant part of b1(omega1))", min=0.0
    )
    static_ratio: float = _static_ratio("engine")
    torque_model: str = _param(
        "-",
        "-",
        "generated torque model: 'linear' = K theta (the paper), 'map' = theta C_max(omega1)",
        kind="choice",
        choices=("linear", "map"),
    )
    full_load_curve: PwlTable | None = _param(
        "N m",
        "engine",
        "full-load torque C_max [N m] versus engine speed omega1 [rad/s]; clamped outside the "
        "knots; required if torque_model = 'map'",
        kind="table",
        table=_FULL_LOAD_SPEC,
        default=None,
    )

    def _check(self) -> None:
        if self.torque_model == "map" and self.full_load_curve is None:
            raise ParameterError(
                "engine.full_load_curve = None: required when engine.torque_model = 'map'"
            )
        if self.full_load_curve is not None:
            for xi, yi in zip(self.full_load_curve.x, self.full_load_curve.y, strict=True):
                if yi < 0.0:
                    raise ParameterError(
                        f"engine.full_load_curve: C_max must be >= 0, but "
                        f"C_max({_fmt(xi)})={_fmt(yi)}"
                    )


_FLAT_MU = PwlTable((0.0,), (1.0,), "clutch.mu_table", **_MU_SPEC._asdict())
#: relative tolerance of ``max(pedal_map) = 1`` (shape) or ``= k12_max`` (a map in N m)
_PEDAL_MAP_RTOL = 1e-9


@dataclass(frozen=True, slots=True, kw_only=True)
class ClutchParams(_Section):
    """Dry clutch: disc inertia, capacity ``k12(x_c)`` and slip dependence of the friction.

    Capacity (the paper's k12(x_c), eq. (1); k13(x_c) of the reduced model, eq. (5), Fig. 12):
    ``k12(x_c) = k12_max * pedal_map(x_c)`` [N m] at zero slip, times ``mu_table(|slip|)`` while
    slipping. ``pedal_map`` is the shape k12/k12_max [-]: 1 at its first knot, non-increasing in
    the release position x_c [m], within [0, 1]. A map given in N m (any value > 1, the older
    form) is divided by ``k12_max``; its largest value must equal ``k12_max`` (relative 1e-9).
    The drivetrain turns the product into the clutch's chain element
    (:func:`~drivetrain_ctrl.plant.drivetrain.clutch_friction`), which evaluates it.
    """

    _section: ClassVar[str] = "clutch"

    J2: float = _param(
        "kg m^2", "primary", "clutch disc (damper input) inertia", min=0.0, min_inclusive=False
    )
    b2: float = _param("N m s/rad", "primary", "viscous friction of the clutch disc", min=0.0)
    k12_max: float = _param(
        "N m",
        "primary",
        "fully engaged clutch torque capacity: the scale of k12(x_c) = k12_max * pedal_map(x_c)",
        min=0.0,
        min_inclusive=False,
    )
    pedal_map: PwlTable = _param(
        "-",
        "primary",
        "shape of the clutch capacity, k12/k12_max [-] in [0, 1], versus actuator/pedal position "
        "x_c [m]; 1 at the first knot, non-increasing (larger x_c = clutch more open); clamped "
        "outside the knots. A map in N m (values > 1) is read and divided by k12_max",
        kind="table",
        table=_PEDAL_SPEC,
    )
    static_ratio: float = _static_ratio("clutch")
    mu_table: PwlTable = _param(
        "-",
        "-",
        "friction coefficient ratio mu(slip)/mu(0) [-] versus slip speed |omega1 - omega2| "
        "[rad/s] (evaluated at |slip|, clamped beyond the last knot); starts at (0, 1)",
        kind="table",
        table=_MU_SPEC,
        default=_FLAT_MU,
    )

    def _check(self) -> None:
        pm = self.pedal_map
        top = max(pm.y)
        in_nm = top > 1.0  # the older form: k12 [N m] itself
        what = "k12" if in_nm else "k12/k12_max"
        for xi, yi in zip(pm.x, pm.y, strict=True):
            if yi < 0.0:
                raise ParameterError(
                    f"clutch.pedal_map: {what} must be >= 0, but {what}({_fmt(xi)})={_fmt(yi)}"
                )
        for i in range(1, len(pm.x)):
            if pm.y[i] > pm.y[i - 1]:
                raise ParameterError(
                    f"clutch.pedal_map: {what} must be non-increasing in x_c, but "
                    f"{what}({_fmt(pm.x[i - 1])})={_fmt(pm.y[i - 1])} < "
                    f"{what}({_fmt(pm.x[i])})={_fmt(pm.y[i])}"
                )
        if in_nm:
            if abs(top - self.k12_max) > _PEDAL_MAP_RTOL * self.k12_max:
                raise ParameterError(
                    f"clutch.pedal_map: a map in N m (values above 1) must reach "
                    f"clutch.k12_max = {_fmt(self.k12_max)} N m at full engagement, but its "
                    f"largest value is k12({_fmt(pm.x[0])})={_fmt(top)}; give the shape "
                    "k12/k12_max in [0, 1] or make the two agree"
                )
            shape = tuple(yi / self.k12_max for yi in pm.y)
            scaled = PwlTable(pm.x, shape, pm.name, **_PEDAL_SPEC._asdict())
            object.__setattr__(self, "pedal_map", scaled)
        elif abs(top - 1.0) > _PEDAL_MAP_RTOL:
            raise ParameterError(
                f"clutch.pedal_map: the shape k12/k12_max must be 1 at full engagement (its "
                f"first knot), but its largest value is k12/k12_max({_fmt(pm.x[0])})="
                f"{_fmt(top)}; the capacity scale is clutch.k12_max"
            )
        mu = self.mu_table
        if mu.x[0] != 0.0:
            raise ParameterError(
                f"clutch.mu_table: the first slip speed must be 0.0, got x[0]={_fmt(mu.x[0])}"
            )
        if mu.y[0] != 1.0:
            raise ParameterError(
                f"clutch.mu_table: mu(0)/mu(0) must be 1.0, got y[0]={_fmt(mu.y[0])}"
            )
        for xi, yi in zip(mu.x, mu.y, strict=True):
            if yi <= 0.0:
                raise ParameterError(
                    f"clutch.mu_table: mu ratio must be > 0, but mu_ratio({_fmt(xi)})={_fmt(yi)}"
                )


@dataclass(frozen=True, slots=True, kw_only=True)
class DamperParams(_Section):
    """Torsional damper between clutch disc and primary shaft (spring ``phi_e`` + friction k23)."""

    _section: ClassVar[str] = "damper"

    J3: float = _param(
        "kg m^2", "primary", "primary shaft + gearbox input inertia", min=0.0, min_inclusive=False
    )
    b3: float = _param("N m s/rad", "primary", "viscous friction of the primary shaft", min=0.0)
    k23: float = _param("N m", "primary", "damper hysteresis (Coulomb) friction torque", min=0.0)
    static_ratio: float = _static_ratio("damper hysteresis")
    spring: PwlTable = _param(
        "N m",
        "primary",
        "damper spring torque phi_e [N m] versus twist theta_d = theta2 - theta3 [rad], given for "
        "theta_d >= 0 and extended as an odd function; beyond the last knot it is extrapolated "
        "LINEARLY with the last segment's slope (the stop stiffness)",
        kind="table",
        table=_SPRING_SPEC,
    )

    def _check(self) -> None:
        sp = self.spring
        if len(sp.x) < 2:
            raise ParameterError(
                f"damper.spring: needs at least 2 knots (0, 0) and one more, got x = {sp.x}"
            )
        if sp.x[0] != 0.0 or sp.y[0] != 0.0:
            raise ParameterError(
                f"damper.spring: must start at theta_d = 0 with phi_e = 0, got "
                f"phi_e({_fmt(sp.x[0])})={_fmt(sp.y[0])}"
            )
        for i in range(1, len(sp.y)):
            if not sp.y[i] > sp.y[i - 1]:
                raise ParameterError(
                    f"damper.spring: phi_e must be strictly increasing, but "
                    f"phi_e({_fmt(sp.x[i])})={_fmt(sp.y[i])} <= "
                    f"phi_e({_fmt(sp.x[i - 1])})={_fmt(sp.y[i - 1])}"
                )


@dataclass(frozen=True, slots=True, kw_only=True)
class GearboxParams(_Section):
    """Gearbox and differential: ratios, secondary inertia, mesh stiffness, damping and backlash."""

    _section: ClassVar[str] = "gearbox"

    gear_ratios: tuple[float, ...] = _param(
        "-",
        "-",
        "gearbox ratios tau_r = omega3 / omega_sec of gears 1, 2, ...",
        kind="floats",
        min=0.0,
        min_inclusive=False,
    )
    D_c: float = _param(
        "-", "-", "final drive ratio D_c = omega_sec / omega4", min=0.0, min_inclusive=False
    )
    J4: float = _param(
        "kg m^2",
        "secondary",
        "secondary shaft + differential inertia (J25 uses J4 / tau_r^2)",
        min=0.0,
        min_inclusive=False,
    )
    b4: float = _param("N m s/rad", "secondary", "viscous friction of the differential", min=0.0)
    h34: float = _param("N m/rad", "primary", "gear teeth stiffness", min=0.0, min_inclusive=False)
    b34: float = _param("N m s/rad", "primary", "relative (mesh) damping of the gearbox", min=0.0)
    g34_wheel: float = _param(
        "rad",
        "wheel",
        "half backlash of the whole driveline lumped at the gear mesh, stored in the wheel frame "
        "(primary-frame value: g34_primary(gear) = g34_wheel * tau_r * D_c)",
        min=0.0,
    )
    backlash_damping: str = _param(
        "-",
        "-",
        "where the mesh damping b34 acts: 'always' = in contact and in the backlash gap (the "
        "paper: a damper in parallel with the dead-zone spring), 'contact' = only while the "
        "teeth are in contact, none in the gap (as Modelica's ElastoBacklash); the reduced "
        "model's lumped shaft damping b_t follows it. The same model when g34_wheel = 0",
        kind="choice",
        choices=("always", "contact"),
        default="always",
    )

    @property
    def n_gears(self) -> int:
        """Number of forward gears [-]."""
        return len(self.gear_ratios)

    def _gear_index(self, gear: int) -> int:
        n = len(self.gear_ratios)
        if isinstance(gear, bool) or not isinstance(gear, int | np.integer) or not 1 <= gear <= n:
            raise ValueError(f"gear = {gear!r}: must be an integer gear number in 1..{n}")
        return int(gear) - 1

    def tau_r(self, gear: int) -> float:
        """Gearbox ratio tau_r = omega3 / omega_sec [-] of ``gear`` (1-based)."""
        return self.gear_ratios[self._gear_index(gear)]

    def tau_t(self, gear: int) -> float:
        """Total ratio tau_t = tau_r * D_c = omega3 / omega4 [-] of ``gear`` (1-based)."""
        return self.tau_r(gear) * self.D_c

    def g34_primary(self, gear: int) -> float:
        """Half backlash referred to the primary shaft [rad]: g34_wheel * tau_t(gear)."""
        return self.g34_wheel * self.tau_t(gear)


@dataclass(frozen=True, slots=True, kw_only=True)
class DrivelineParams(_Section):
    """Half-shafts, tyres/hubs and wheels (wheel frame, omega4 / omega5)."""

    _section: ClassVar[str] = "driveline"

    h45: float = _param(
        "N m/rad",
        "wheel",
        "half-shaft torsional stiffness (both shafts)",
        min=0.0,
        min_inclusive=False,
    )
    b45: float = _param("N m s/rad", "wheel", "half-shaft damping", min=0.0)
    h56: float = _param(
        "N m/rad", "wheel", "tyre/hub torsional stiffness", min=0.0, min_inclusive=False
    )
    b56: float = _param("N m s/rad", "wheel", "tyre/hub damping", min=0.0, min_inclusive=False)
    J5: float = _param(
        "kg m^2", "wheel", "total inertia of the wheels and hubs", min=0.0, min_inclusive=False
    )
    b5: float = _param(
        "N m s/rad", "wheel", "viscous friction of axles and wheels", min=0.0, default=0.0
    )
    tread_fraction: float = _param(
        "-",
        "-",
        "fraction of J5 outboard of the tyre compliance h56 (tyre tread ring, grips or slips on "
        "the road)",
        min=0.0,
        max=1.0,
        min_inclusive=False,
        max_inclusive=False,
    )
    R_p: float = _param("m", "wheel", "wheel (rolling) radius", min=0.0, min_inclusive=False)


@dataclass(frozen=True, slots=True, kw_only=True)
class VehicleParams(_Section):
    """Vehicle body: mass, road loads and tyre-road friction."""

    _section: ClassVar[str] = "vehicle"

    M_v: float = _param("kg", "vehicle", "overall vehicle mass", min=0.0, min_inclusive=False)
    C_x: float = _param("-", "vehicle", "aerodynamic drag coefficient", min=0.0)
    S: float = _param("m^2", "vehicle", "frontal (transverse) area", min=0.0)
    rho_a: float = _param("kg/m^3", "vehicle", "air density", min=0.0)
    f_r: float = _param(
        "-",
        "vehicle",
        "rolling resistance coefficient (k_v = f_r M_v g cos(alpha))",
        min=0.0,
        max=1.0,
        max_inclusive=False,
    )
    b_v: float = _param("N s/m", "vehicle", "viscous vehicle friction", min=0.0)
    mu_tyre: float = _param(
        "-", "vehicle", "tyre-road friction coefficient", min=0.0, max=2.0, min_inclusive=False
    )
    drive_axle_load_fraction: float = _param(
        "-",
        "vehicle",
        "fraction of the vehicle weight on the driven axle",
        min=0.0,
        max=1.0,
        min_inclusive=False,
    )
    rolling_static_ratio: float = _static_ratio("rolling resistance")
    tyre_static_ratio: float = _static_ratio("tyre-road")

    def k_v(self, alpha: FloatOrArray = 0.0) -> FloatOrArray:
        """Rolling resistance force k_v = f_r M_v g cos(alpha) [N] on slope ``alpha`` [rad]."""
        return self.f_r * self.M_v * GRAVITY * np.cos(alpha)

    def k_w(self, alpha: FloatOrArray = 0.0) -> FloatOrArray:
        """Tyre-road Coulomb limit k_w = mu_tyre F_z,drive cos(alpha) [N] on slope ``alpha`` [rad].

        F_z,drive = drive_axle_load_fraction * M_v * g.
        """
        fz = self.drive_axle_load_fraction * self.M_v * GRAVITY
        return self.mu_tyre * fz * np.cos(alpha)


@dataclass(frozen=True, slots=True, kw_only=True)
class BrakeParams(_Section):
    """Service brake (e.g. hill hold)."""

    _section: ClassVar[str] = "brake"

    capacity_max: float = _param(
        "N m", "wheel", "maximum service-brake torque at the wheels (all wheels)", min=0.0
    )
    static_ratio: float = _static_ratio("brake")


@dataclass(frozen=True, slots=True, kw_only=True)
class ActuatorParams(_Section):
    """Clutch actuator: ``X_C/X_R = omega_a^2 / (s^2 + 2 delta_a omega_a s + omega_a^2)``."""

    _section: ClassVar[str] = "actuator"

    omega_a: float = _param(
        "rad/s", "-", "natural frequency of the actuator", min=0.0, min_inclusive=False
    )
    delta_a: float = _param("-", "-", "damping ratio of the actuator", min=0.0, min_inclusive=False)
    x_min: float = _param("m", "-", "lower stroke limit of the actuator position x_c")
    x_max: float = _param("m", "-", "upper stroke limit of the actuator position x_c")

    def _check(self) -> None:
        if not self.x_max > self.x_min:
            raise ParameterError(
                f"actuator.x_max = {_fmt(self.x_max)}: must be > actuator.x_min = "
                f"{_fmt(self.x_min)} [m]"
            )

    def outside_stroke(self, field: str, x: float) -> str | None:
        """None if position ``x`` [m] lies within the stroke ``[x_min, x_max]``, else the message
        naming ``field`` (the caller raises its own error class with it)."""
        if self.x_min <= x <= self.x_max:
            return None
        return (
            f"{field} = {_fmt(x)} [m]: must lie within the actuator stroke "
            f"[{_fmt(self.x_min)}, {_fmt(self.x_max)}] [m]"
        )


_SECTIONS: dict[str, type[_Section]] = {
    "engine": EngineParams,
    "clutch": ClutchParams,
    "damper": DamperParams,
    "gearbox": GearboxParams,
    "driveline": DrivelineParams,
    "vehicle": VehicleParams,
    "brake": BrakeParams,
    "actuator": ActuatorParams,
}

_FIELD_META: dict[str, Mapping[str, Any]] = {
    f"{s}.{f.name}": f.metadata for s, cls in _SECTIONS.items() for f in fields(cast(Any, cls))
}
_FIELD_ORDER: dict[str, int] = {path: i for i, path in enumerate(_FIELD_META)}


def field_paths() -> list[str]:
    """All dotted field paths (``"engine.J1"``, ...) in declaration order."""
    return list(_FIELD_META)


def field_info(path: str) -> dict[str, Any]:
    """Metadata of the field at dotted ``path``, e.g. ``field_info("engine.J1")``.

    Returns a dict with ``unit``, ``frame``, ``description``, ``min``, ``max`` (``None`` =
    unbounded), ``min_inclusive``, ``max_inclusive``, ``kind`` (``"float"``, ``"floats"``,
    ``"table"``, ``"choice"``), ``choices``, ``optional`` (may be omitted in a file) and
    ``default`` (its value then). For tables, ``unit`` is the unit of ``y`` and ``x_name``,
    ``x_unit``, ``y_name``, ``y_unit``, ``extrapolation``, ``symmetry`` are added.
    """
    try:
        md = _FIELD_META[path]
    except KeyError:
        raise ParameterError(
            f"{path}: unknown parameter{did_you_mean(path, _FIELD_META)}"
        ) from None
    info = {k: v for k, v in md.items() if k != "table"}
    if md["table"] is not None:
        info.update(md["table"]._asdict())
    return info


def _canonical_provenance(value: object) -> tuple[tuple[str, str], ...]:
    if isinstance(value, Mapping):
        items = list(value.items())
    elif isinstance(value, Iterable) and not isinstance(value, str | bytes):
        items = []
        for item in value:
            if not (isinstance(item, tuple | list) and len(item) == 2):
                raise ParameterError(
                    f"provenance: entries must be (field path, text) pairs, got {_fmt(item)}"
                )
            items.append((item[0], item[1]))
    else:
        raise ParameterError(f"provenance = {_fmt(value)}: must be a mapping field path -> text")
    seen: dict[str, str] = {}
    for key, text in items:
        if not isinstance(key, str) or key not in _FIELD_META:
            raise ParameterError(
                f"provenance.{key}: {key!r} names no parameter{did_you_mean(str(key), _FIELD_META)}"
            )
        if not isinstance(text, str):
            raise ParameterError(f"provenance.{key} = {_fmt(text)}: must be a str")
        if key in seen:
            raise ParameterError(f"provenance.{key}: given twice")
        seen[key] = text
    return tuple(sorted(seen.items(), key=lambda kv: _FIELD_ORDER[kv[0]]))


@dataclass(frozen=True, slots=True, kw_only=True)
class DrivetrainParams:
    """All parameters of the drivetrain model, one immutable section per component.

    ``provenance`` holds ``(dotted field path, source text)`` pairs (stored in field order; a
    mapping is accepted and converted). Use :meth:`replace` to derive a modified, validated copy.
    """

    name: str
    description: str
    engine: EngineParams
    clutch: ClutchParams
    damper: DamperParams
    gearbox: GearboxParams
    driveline: DrivelineParams
    vehicle: VehicleParams
    brake: BrakeParams
    actuator: ActuatorParams
    provenance: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        for key in ("name", "description"):
            value = getattr(self, key)
            if not isinstance(value, str):
                raise ParameterError(f"meta.{key} = {_fmt(value)}: must be a str")
        if not self.name.strip():
            raise ParameterError("meta.name = '': must not be empty")
        for key, cls in _SECTIONS.items():
            value = getattr(self, key)
            if not isinstance(value, cls):
                raise ParameterError(
                    f"{key} = {_fmt(value)}: must be a {cls.__name__}, not {type(value).__name__}"
                )
        object.__setattr__(self, "provenance", _canonical_provenance(self.provenance))

    def provenance_dict(self) -> dict[str, str]:
        """The provenance as a dict ``{dotted field path: source text}``."""
        return dict(self.provenance)

    def get(self, path: str) -> Any:
        """The value of the field at dotted ``path`` (e.g. ``"clutch.k12_max"``; SI units)."""
        if path not in _FIELD_META:
            raise ParameterError(f"{path}: unknown parameter{did_you_mean(path, _FIELD_META)}")
        section, _, name = path.partition(".")
        return getattr(getattr(self, section), name)

    def replace(self, **changes: Any) -> DrivetrainParams:
        """A new, validated set with fields replaced by dotted path.

        Example: ``p.replace(**{"clutch.k12_max": 300.0, "name": "strong clutch"})`` (the
        clutch capacity ``k12_max * pedal_map(x_c)`` scaled by 1.2 at every x_c). Keys are
        dotted field paths, top-level field names (``name``, ``description``, ``provenance``) or
        whole sections. Tables may be given as :class:`~drivetrain_ctrl.core.tables.PwlTable` or ``{"x": [...], "y": [...]}``.
        """
        top: dict[str, Any] = {}
        per_section: dict[str, dict[str, Any]] = {}
        top_names = [f.name for f in fields(self)]
        for path, value in changes.items():
            section, dot, name = path.partition(".")
            if not dot:
                if path not in top_names:
                    raise ParameterError(
                        f"{path}: unknown parameter{did_you_mean(path, [*top_names, *_FIELD_META])}"
                    )
                top[path] = value
            elif path not in _FIELD_META:
                raise ParameterError(f"{path}: unknown parameter{did_you_mean(path, _FIELD_META)}")
            else:
                per_section.setdefault(section, {})[name] = value
        for section, section_changes in per_section.items():
            base = top.get(section, getattr(self, section))
            top[section] = dataclasses.replace(base, **section_changes)
        return dataclasses.replace(self, **top)

    def with_values(self, changes: Mapping[str, Any]) -> DrivetrainParams:
        """Same as :meth:`replace` with a mapping ``{dotted path: value}``."""
        return self.replace(**dict(changes))


# --------------------------------------------------------------------------------------------------
# dict / TOML conversion
# --------------------------------------------------------------------------------------------------


def _plain(value: object) -> object:
    if isinstance(value, PwlTable):
        return {"x": list(value.x), "y": list(value.y)}
    if isinstance(value, tuple):
        return list(value)
    return value


def params_to_dict(p: DrivetrainParams) -> dict[str, Any]:
    """Convert ``p`` to plain Python data with the layout of a parameter file.

    ``{"meta": {"name", "description"}, "engine": {...}, ..., "provenance": {path: text}}``; tables
    become ``{"x": [...], "y": [...]}``, tuples become lists, fields set to ``None`` are left out.
    """
    out: dict[str, Any] = {"meta": {"name": p.name, "description": p.description}}
    for key in _SECTIONS:
        section = getattr(p, key)
        out[key] = {
            f.name: _plain(getattr(section, f.name))
            for f in fields(section)
            if getattr(section, f.name) is not None
        }
    out["provenance"] = p.provenance_dict()
    return out


def _mapping(path: str, value: object) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ParameterError(f"{path} = {_fmt(value)}: must be a table (section)")
    return value


def params_from_dict(data: Mapping[str, Any], *, where: Path | None = None) -> DrivetrainParams:
    """Build and validate :class:`DrivetrainParams` from the layout of :func:`params_to_dict`.

    A top-level ``base`` names a set that ``data`` overrides (module docstring); a relative base
    path is taken from directory ``where`` (None: the working directory).

    Unknown keys raise :class:`ParameterError` (with a suggestion); so do missing keys, except the
    optional fields listed in the module docstring. ``provenance`` may be omitted. A retired
    section (:data:`RETIRED_SECTIONS`, e.g. ``law6``) and its provenance entries are ignored with
    a :class:`ParameterSectionWarning` naming the section and its values.
    """
    data = _drop_retired_sections(_with_base(_mapping("<parameters>", data), where))
    allowed = ["meta", *_SECTIONS, "provenance"]
    for key in data:
        if key not in allowed:
            raise ParameterError(f"{key}: unknown section{did_you_mean(str(key), allowed)}")
    for key in ("meta", *_SECTIONS):
        if key not in data:
            raise ParameterError(f"{key}: missing section [{key}]")
    meta = _mapping("meta", data["meta"])
    for key in meta:
        if key not in ("name", "description"):
            raise ParameterError(
                f"meta.{key}: unknown key{did_you_mean(str(key), ('name', 'description'))}"
            )
    for key in ("name", "description"):
        if key not in meta:
            raise ParameterError(f"meta.{key}: missing key")
    sections: dict[str, Any] = {}
    for key, cls in _SECTIONS.items():
        raw = _mapping(key, data[key])
        names = [f.name for f in fields(cast(Any, cls))]
        for name in raw:
            if name not in names:
                raise ParameterError(
                    f"{key}.{name}: unknown parameter{did_you_mean(str(name), names)}"
                )
        kwargs: dict[str, Any] = {}
        for f in fields(cast(Any, cls)):
            if f.name in raw:
                kwargs[f.name] = raw[f.name]
            elif not f.metadata["optional"]:
                md = f.metadata
                raise ParameterError(
                    f"{key}.{f.name}: missing parameter ({md['description']} [{md['unit']}])"
                )
        sections[key] = cls(**kwargs)
    return DrivetrainParams(
        name=meta["name"],
        description=meta["description"],
        provenance=data.get("provenance", {}),
        **sections,
    )


def _with_base(
    data: Mapping[str, Any], where: Path | None, seen: tuple[Path, ...] = ()
) -> Mapping[str, Any]:
    """``data`` merged onto its ``base`` set (module docstring), recursively; ``data`` itself if it
    names none. ``where``: the directory of the file ``data`` comes from (None: the working
    directory), for a relative base path; ``seen``: the files above in the chain (a circle is an
    error)."""
    if "base" not in data:
        return data
    base = data["base"]
    if not isinstance(base, str) or not base.strip():
        raise ParameterError(
            f"base = {_fmt(base)}: must be a parameter set name or the path of a TOML file"
        )
    try:
        source = _resolve_source(base)
    except ValueError as exc:  # an unknown set name
        raise ParameterError(f"base = {base!r}: {exc}") from None
    if not source.is_absolute() and source.parent != PARAMETER_SETS_DIR and where is not None:
        source = where / source
    source = source.resolve()
    if source in seen:
        chain = " -> ".join(str(s) for s in (*seen, source))
        raise ParameterError(f"base = {base!r}: the sets name each other in a circle ({chain})")
    if not source.is_file():
        raise ParameterError(f"base = {base!r}: no such parameter file ({source})")
    parent = _with_base(read_toml(source, error=ParameterError), source.parent, (*seen, source))
    meta = data.get("meta")
    if not isinstance(meta, Mapping) or "name" not in meta:
        raise ParameterError(
            f"meta.name: missing key (a set with base = {base!r} needs a name of its own)"
        )
    merged: dict[str, Any] = {k: v for k, v in parent.items() if k != "provenance"}
    overridden: set[str] = set()
    for key, value in data.items():
        if key in ("base", "provenance"):
            continue
        old = merged.get(key)
        if isinstance(value, Mapping) and isinstance(old, Mapping):
            merged[key] = {**old, **value}
            overridden |= {f"{key}.{k}" for k in value}
        else:
            merged[key] = value
            if isinstance(value, Mapping):
                overridden |= {f"{key}.{k}" for k in value}
    prov = {k: v for k, v in dict(parent.get("provenance", {})).items() if k not in overridden}
    own = data.get("provenance", {})
    merged["provenance"] = {**prov, **(dict(own) if isinstance(own, Mapping) else {})}
    if not isinstance(own, Mapping):
        merged["provenance"] = own  # reported by params_from_dict
    return merged


def _drop_retired_sections(data: Mapping[str, Any]) -> Mapping[str, Any]:
    """``data`` without the sections of :data:`RETIRED_SECTIONS` and their provenance entries,
    warning :class:`ParameterSectionWarning` once per section found."""
    found = [key for key in RETIRED_SECTIONS if key in data]
    if not found:
        return data
    for key in found:
        raw = data[key]
        values = (
            ", ".join(f"{k} = {_fmt(v)}" for k, v in raw.items())
            if isinstance(raw, Mapping)
            else _fmt(raw)
        )
        warnings.warn(
            f"{key}: section [{key}] ({values}) ignored; {RETIRED_SECTIONS[key]}",
            ParameterSectionWarning,
            stacklevel=3,
        )
    out = {k: v for k, v in data.items() if k not in found}
    prov = out.get("provenance")
    if isinstance(prov, Mapping):
        out["provenance"] = {k: v for k, v in prov.items() if str(k).partition(".")[0] not in found}
    return out


def available_parameter_sets() -> list[str]:
    """Names of the built-in parameter sets (the stems of ``parameter_sets/*.toml``)."""
    return sorted(p.stem for p in PARAMETER_SETS_DIR.glob("*.toml"))


#: the built-in set that ``"default"`` names (and :func:`default_params` loads)
DEFAULT_SET = "passenger-car"


def _resolve_source(source: str | Path) -> Path:
    if isinstance(source, Path):
        return source
    if not isinstance(source, str):
        raise TypeError(
            f"source = {source!r}: a parameter set name or a path to a .toml file, "
            f"not {type(source).__name__}"
        )
    sets = available_parameter_sets()
    if source == "default" and not (PARAMETER_SETS_DIR / "default.toml").is_file():
        source = DEFAULT_SET
    if source in sets:
        return PARAMETER_SETS_DIR / f"{source}.toml"
    looks_like_path = source.endswith(".toml") or "/" in source or "\\" in source
    if looks_like_path or Path(source).is_file():
        return Path(source)
    raise ValueError(
        f"unknown parameter set {source!r}{did_you_mean(source, sets)} "
        f"(available: {', '.join(sets) or 'none'}, 'default' = {DEFAULT_SET!r}; or give a path "
        "to a .toml file)"
    )


def load_params(source: str | Path) -> DrivetrainParams:
    """Load and validate a parameter set: a built-in set name (e.g. ``"passenger-car"``; ``"default"``
    is the built-in default set, :data:`DEFAULT_SET`) or a path to a TOML file. All values are SI (see :func:`field_info` for units and frames).

    Raises :class:`ParameterError` for invalid, unknown or missing parameters (message suffixed with
    the file), :class:`ValueError` for an unknown set name, :class:`TypeError` for a ``source``
    that is neither a string nor a path, and :class:`FileNotFoundError` for a missing file.
    """

    path = _resolve_source(source)
    seen = (path.resolve(),)

    def from_dict(d: dict[str, Any]) -> DrivetrainParams:
        return params_from_dict(_with_base(d, path.parent, seen))

    return load_toml_as(path, from_dict, error=ParameterError)


def save_params(params: DrivetrainParams, path: str | Path) -> Path:
    """Write ``params`` to the TOML file ``path`` (SI units) and return the path.

    ``load_params(save_params(p, path)) == p`` holds exactly (floats are written with ``repr``).
    """
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    header = (
        f"# drivetrain_ctrl parameter set {params.name!r}, written by save_params.\n"
        "# SI units; units and frames of each field: drivetrain_ctrl.plant.params.field_info().\n\n"
    )
    out.write_text(header + tomli_w.dumps(params_to_dict(params)), encoding="utf-8")
    return out


@functools.lru_cache(maxsize=1)
def default_params() -> DrivetrainParams:
    """The built-in default set, :data:`DEFAULT_SET` (cached; the object is immutable)."""
    return load_params(DEFAULT_SET)
