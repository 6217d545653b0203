"""Exact switching simulation of a chain model: options, runner and :class:`SimulationResult`.

>>> from drivetrain_ctrl.plant.params import default_params
>>> from drivetrain_ctrl.plant.drivetrain import full_model
>>> from drivetrain_ctrl import signals as sg
>>> from drivetrain_ctrl.sim.simulator import simulate
>>> dt = full_model(default_params())
>>> x0 = dt.rigid_state(omega_engine=200.0, v_vehicle=0.0, throttle=0.5)
>>> res = simulate(dt.model, x0, {"throttle": sg.constant(0.5),
...                               "pedal": sg.ramp(0.2, 2.2, 0.11, 0.03),
...                               "brake": sg.constant(0.0)}, t_end=3.0)
>>> res.status
'ok'
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from .. import kernels as K
from ..control.blocks import require_controller
from ..core.signals import Signal, constant, pack_signals
from ..core.validate import is_finite_real
from ..plant.model import Model
from . import series
from .compile_notice import announce_compile

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

__all__ = [
    "SimulationOptions",
    "SimulationResult",
    "Event",
    "ZenoError",
    "InputRangeError",
    "SecondLawError",
    "simulate",
]

F64 = NDArray[np.float64]


class ZenoError(RuntimeError):
    """Events accumulate (Zeno behaviour): the run was stopped."""


class SecondLawError(RuntimeError):
    """An element's dissipated power is clearly negative (it supplies energy): a modelling error
    (``SimulationOptions(second_law="raise")``)."""


#: what :class:`SimulationOptions` ``second_law`` may ask for
SECOND_LAW_ACTIONS = ("warn", "raise", "ignore")

#: a dissipated power counts as clearly negative below ``-SECOND_LAW_RTOL`` times the run's
#: largest total dissipated power (plus 1e-12 W): round-off of a slip speed located to zero at an
#: event is far below it
SECOND_LAW_RTOL = 1e-9


class InputRangeError(ValueError):
    """An input signal leaves the model's physical range for that input (``Model.input_ranges``)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class SimulationOptions:
    """Integrator settings (all keyword-only).

    rtol, atol: local error tolerances (atol in state units: rad/s, m/s, rad, m). Keep rtol <=
    1e-7: the full drivetrain has a stiff, lightly damped gear-mesh mode (about 600 Hz, damping
    ratio a few per cent) that local errors of a loose tolerance excite, and the damper friction
    then sticks and slips with it (spurious events). The default rtol 1e-8 meets 1e-5 s on event
    times; atol only matters for states near zero (a vehicle at rest, spring twists) and the
    default 1e-7 is three orders below the 1e-4 rad/s speed accuracy the benchmark checks (see
    the performance page of the docs and ``benchmarks/bench_simulate.py``).
    h_max [s]: largest step, so that no stick or break-away episode shorter than about ``h_max``
    is stepped over; h_init [s]: first step (at most h_max);
    tol_w [rad/s or m/s]: relative speed treated as zero when deciding modes at an event;
    energy: integrate supplied work and dissipated energies; zeno_count events within
    zeno_window [s] stop the run (:class:`ZenoError`; a guard crossing that changes no mode counts
    as an event here, so that crossings repeating at one instant stop the run at once).
    smoothing [rad/s or m/s]: replace every Coulomb law ``k sgn(w)`` by ``k tanh(w / smoothing)``
    (no stick: for comparison only; the default ``None`` is the exact switching model).
    record_every: record every k-th accepted step (the start, the end and every step that ends
    at an event or an input breakpoint are always recorded); events and integrated energies are
    exact either way, figures taken from the samples (extrema) are of the samples kept. For a
    fixed output grid instead, give ``simulate(..., t_eval=...)``.
    second_law: what a clearly negative dissipated power does (an element that supplies energy,
    a modelling error): ``"warn"`` (a ``RuntimeWarning`` naming the element and the time; the
    default), ``"raise"`` (:class:`SecondLawError`) or ``"ignore"``. The most negative power of
    the run is in ``res.stats["dissipation_min_W"]`` either way (needs ``energy``).
    """

    rtol: float = 1e-8
    atol: float = 1e-7
    h_max: float = 1e-3
    h_init: float = 1e-5
    tol_w: float = 1e-8
    energy: bool = True
    zeno_count: int = 50
    zeno_window: float = 1e-6
    max_events: int = 100_000
    max_steps: int = 10_000_000
    smoothing: float | None = None
    record_every: int = 1
    second_law: str = "warn"

    def __post_init__(self) -> None:
        for name in ("rtol", "atol", "h_max", "h_init", "tol_w", "zeno_window"):
            v = getattr(self, name)
            if not is_finite_real(v) or v <= 0:
                raise ValueError(f"SimulationOptions.{name} = {v!r}: must be a finite number > 0")
            object.__setattr__(self, name, float(v))
        if not self.rtol < 1e-2:
            raise ValueError(
                f"SimulationOptions.rtol = {self.rtol!r}: must be < 1e-2 (keep it <= 1e-7 on the "
                "full drivetrain, see the class docstring)"
            )
        if isinstance(self.energy, np.bool_):
            object.__setattr__(self, "energy", bool(self.energy))
        if not isinstance(self.energy, bool):
            raise ValueError(f"SimulationOptions.energy = {self.energy!r}: must be True or False")
        if self.smoothing is not None and (
            not is_finite_real(self.smoothing) or self.smoothing <= 0
        ):
            raise ValueError(
                f"SimulationOptions.smoothing = {self.smoothing!r}: must be None or > 0"
            )
        for name in ("zeno_count", "max_events", "max_steps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 2:
                raise ValueError(f"SimulationOptions.{name} = {v!r}: must be an integer >= 2")
            object.__setattr__(self, name, int(v))
        v = self.record_every
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"SimulationOptions.record_every = {v!r}: must be an integer >= 1")
        object.__setattr__(self, "record_every", int(v))
        if self.second_law not in SECOND_LAW_ACTIONS:
            raise ValueError(
                f"SimulationOptions.second_law = {self.second_law!r}: must be one of "
                f"{', '.join(map(repr, SECOND_LAW_ACTIONS))}"
            )


class Event(NamedTuple):
    """A mode change: time [s], element name, from-mode and to-mode names. The element is a
    friction element, a table (backlash, spring, capacity map) or, in closed loop, a controller
    block (``controller.sign``, ``.saturation``, ``.lookup``, ``.rate_limit``, ``.latch``).

    A named tuple (immutable; built hundreds of times per run, where a frozen dataclass's
    ``__init__`` cost about 1 us each)."""

    t: float
    element: str
    from_mode: str
    to_mode: str


_STATUS = {
    K.OK: "ok",
    K.ZENO: "zeno",
    K.MAX_EVENTS: "max_events",
    K.MAX_STEPS: "max_steps",
    K.STEP_TOO_SMALL: "step_too_small",
    K.TOO_MANY_CANDIDATES: "too_many_candidates",
}


@dataclass(frozen=True)
class SimulationResult:
    """Trajectory of a hybrid simulation.

    ``t`` (N,) [s]; ``x`` (N, nx) states (units: ``model.state_units``); ``u`` (N, nu) inputs;
    ``fm`` (N, nf) friction mode codes and ``reg`` (N, nt) table regions; ``events``;
    ``work_in`` (N,) [J] supplied work; ``dissipated`` (N, k) [J] per element
    (``model.power_names()``); ``stats`` (steps, rejected steps, nfev, wall time [s]);
    ``smoothing`` [rad/s or m/s]: the run's tanh smoothing of the Coulomb laws (None: exact
    switching), which the torques computed from the result use too.

    The samples are the integrator's accepted steps (every k-th with
    ``SimulationOptions(record_every=k)``) or the ``t_eval`` grid the run was given; for values
    at any other times use :meth:`sample`, not interpolation of the samples.
    """

    model: Model
    t: F64
    x: F64
    u: F64
    fm: NDArray[np.int64]
    reg: NDArray[np.int64]
    events: tuple[Event, ...]
    work_in: F64 | None
    dissipated: F64 | None
    status: str
    stats: dict[str, float] = field(default_factory=dict)
    extras: dict[str, Any] = field(default_factory=dict)
    smoothing: float | None = None
    #: re-runs the simulation with an output grid (``t_eval``): see :meth:`sample`
    rerun: Callable[..., SimulationResult] | None = field(default=None, repr=False, compare=False)

    def _data(self) -> K.ChainData:
        """The model's arrays as the run used them (with the smoothing, if any)."""
        return _smoothed(self.model, self.smoothing)

    # -- access --------------------------------------------------------------------------------
    def state(self, name: str) -> F64:
        """Time series of state ``name`` (see ``model.state_names``)."""
        return self.x[:, self.model.state_index(name)]

    def mode_series(self, element: str) -> list[str]:
        """Mode name of friction element or backlash ``element`` at every sample (``"smoothed"``
        for every friction element of a run with tanh smoothing: it has no stick/slip modes)."""
        m = self.model
        for f, fi in enumerate(m.frictions):
            if fi.name == element:
                if self.smoothing is not None:
                    return ["smoothed"] * self.t.shape[0]
                return [fi.mode_names[c] for c in self.fm[:, f]]
        for k, ti in enumerate(m.tables):
            if ti.name == element and ti.region_names is not None:
                return [ti.region_names[r] for r in self.reg[:, k]]
        raise KeyError(f"no moded element {element!r}")

    def coupling_torques(self) -> F64:
        """(N, m) torque of every coupling [N m] in its upstream frame (incl. stuck torques)."""
        return series.coupling_torques(self._data(), self.x, self.u, self.fm, self.reg)

    def source_torques(self) -> dict[str, F64]:
        """Torque [N m] of every lagged source (the engine's C_G) at every sample."""
        D = self.model.data
        out: dict[str, F64] = {}
        for j, src in enumerate(self.model.chain.sources):
            lag = self.x[:, int(D.l_x[j])]
            gain = np.full(lag.shape, float(D.l_gain[j]))
            kt = int(D.l_table[j])
            if kt >= 0:
                w = self.x[:, int(D.l_body[j])]
                r = self.reg[:, kt]
                gain = gain * (D.t_s[kt, r] * w + D.t_o[kt, r])
            out[src.name] = gain * lag
        return out

    def stored_energy(self) -> F64:
        """(N,) stored energy [J] evaluated from the state."""
        return series.stored_energy(self.model.data, self.x)

    @property
    def energy_residual_rel(self) -> float:
        """``|dE_stored - W_in + sum(E_diss)| / max(W_in, max E_stored)`` at the end of the run."""
        if self.work_in is None or self.dissipated is None:
            raise ValueError("energy was not integrated (SimulationOptions(energy=False))")
        E = self.stored_energy()
        dE = E[-1] - E[0]
        res = dE - self.work_in[-1] + float(np.sum(self.dissipated[-1]))
        scale = max(abs(float(self.work_in[-1])), float(np.max(np.abs(E))), 1e-300)
        return float(abs(res) / scale)

    def lockup_time(
        self, element: str = "clutch", *, min_duration: float = 0.2, after: float = 0.0
    ) -> float | None:
        """Lock-up time [s]: the start of the first stuck phase of friction ``element``, entered
        from slip at or after ``after`` [s], that lasts at least ``min_duration`` [s] (a phase
        still running at the end of the run counts if it has lasted that long). None if there is
        none (never locks, or locks only briefly, or is stuck from the start and stays so)."""
        for nm, v in (("min_duration", min_duration), ("after", after)):
            if not is_finite_real(v):
                raise ValueError(f"lockup_time: {nm} = {v!r} [s]: must be a finite number")
        if min_duration < 0:
            raise ValueError(f"lockup_time: min_duration = {min_duration!r} [s]: must be >= 0")
        if self.t.shape[0] and after > self.t[-1]:
            raise ValueError(
                f"lockup_time: after = {after!r} [s] is past the end of the run "
                f"({float(self.t[-1]):.6g} s)"
            )
        phases = self.stuck_phases(element)
        for t0, t1 in phases:
            if t0 >= after and t1 - t0 >= min_duration:
                return t0
        return None

    def stuck_phases(self, element: str = "clutch") -> list[tuple[float, float]]:
        """``(start, end)`` [s] of every stuck phase of friction ``element`` entered from another
        mode (the end of a phase still running is the end of the run); from the event list, so
        exact whatever was recorded."""
        f = self.model.friction_index(element)
        if self.smoothing is not None:
            return []
        stuck_name = self.model.frictions[f].mode_names[K.STUCK]
        evs = [e for e in self.events if e.element == element]
        # the mode at the start: before the first event, else the (constant) recorded one
        stuck = evs[0].from_mode == stuck_name if evs else bool(self.fm[0, f] == K.STUCK)
        start: float | None = None
        out: list[tuple[float, float]] = []
        for e in evs:
            now = e.to_mode == stuck_name
            if now and not stuck:
                start = e.t
            elif stuck and not now and start is not None:
                out.append((start, e.t))
                start = None
            stuck = now
        if start is not None:
            out.append((start, self.t_last))
        return out

    def sample(self, t: Any) -> SimulationResult:
        """The run at times ``t`` [s] (any order; within the run), exact to the integrator's
        accuracy: the same run again, recording the integrator's continuous extension at ``t``
        (same steps, same events). At an event time the value is the left limit (the state and
        modes just before the event's decision). Returns a :class:`SimulationResult` whose
        samples are ``t`` (sorted, duplicates kept once)."""
        if self.rerun is None:
            raise ValueError("this result cannot be re-sampled (it was not made by simulate())")
        tt = np.unique(_check_times(t, "sample: t", self.t0, self.t_last))
        return self.rerun(t_eval=tt)

    @property
    def t0(self) -> float:
        """Start time of the run [s]."""
        return float(self.stats.get("t0", self.t[0]))

    @property
    def t_last(self) -> float:
        """Time the run reached [s] (``t_end`` unless it stopped early)."""
        return float(self.stats.get("t_last", self.t[-1]))

    def to_dataframe(self, t: Any = None) -> pd.DataFrame:
        """Samples as a pandas DataFrame; column names carry units, e.g. ``omega_engine [rad/s]``.
        With ``t`` [s], the values at those times (:meth:`sample`) instead of the recorded steps.

        Coupling torques ``T_<coupling>`` are in the frame of the coupling's upstream body (e.g.
        ``T_axle``: the secondary shaft's); a coupling with a ratio also has ``T_<coupling>_out``,
        ratio times that: the torque on its downstream body in that body's frame (``T_axle_out``:
        the half-shaft torque at the wheels). Inputs are ``input_<name> [<unit>]`` where the
        chain gives units (the drivetrain: throttle [-], pedal [m], brake [N m])."""
        import pandas as pd

        if t is not None:
            return self.sample(t).to_dataframe()
        cols: dict[str, Any] = {"t [s]": self.t}
        for j, (nm, un) in enumerate(
            zip(self.model.state_names, self.model.state_units, strict=True)
        ):
            cols[f"{nm} [{un}]"] = self.x[:, j]
        for j, (nm, un) in enumerate(
            zip(self.model.input_names, self.model.input_units, strict=True)
        ):
            cols[f"input_{nm} [{un}]" if un else f"input_{nm}"] = self.u[:, j]
        T = self.coupling_torques()
        bodies = self.model.chain.bodies
        for c, cp in enumerate(self.model.chain.couplings):
            up = "N m" if bodies[c].kind == "rotational" else "N"
            cols[f"T_{cp.name} [{up}]"] = T[:, c]
            if cp.ratio != 1.0 and bodies[c + 1].kind == bodies[c].kind:
                # e.g. the axle: the torque on the downstream body, in its frame (at the wheel)
                cols[f"T_{cp.name}_out [{up}]"] = cp.ratio * T[:, c]
            if bodies[c + 1].kind == "translational" and bodies[c].kind == "rotational":
                # e.g. the tyre: the force on the vehicle
                cols[f"F_{cp.name} [N]"] = cp.ratio * T[:, c]
        for name, torque in self.source_torques().items():
            cols[f"C_{name} [N m]"] = torque
        for fi in self.model.frictions:
            cols[f"mode_{fi.name}"] = self.mode_series(fi.name)
        for ti in self.model.tables:
            if ti.region_names is not None:
                cols[f"mode_{ti.name}"] = self.mode_series(ti.name)
        if self.work_in is not None and self.dissipated is not None:
            cols["work_in [J]"] = self.work_in
            cols["stored_energy [J]"] = self.stored_energy()
            for j, nm in enumerate(self.model.power_names()):
                cols[f"dissipated_{nm} [J]"] = self.dissipated[:, j]
        return pd.DataFrame(cols)

    def events_dataframe(self) -> pd.DataFrame:
        """The event list as a DataFrame (``t [s]``, element, from_mode, to_mode)."""
        import pandas as pd

        return pd.DataFrame(
            {
                "t [s]": [e.t for e in self.events],
                "element": [e.element for e in self.events],
                "from_mode": [e.from_mode for e in self.events],
                "to_mode": [e.to_mode for e in self.events],
            }
        )

    def plot(self, path: str | None = None) -> Any:
        """Overview figure (speeds, torques, modes); saved to ``path`` if given. Returns the figure."""
        from ..reporting.figures import plot_simulation

        return plot_simulation(self, path)


def _smoothed(model: Model, smoothing: float | None) -> K.ChainData:
    """``model.data``, with every Coulomb law smoothed by ``tanh(w / smoothing)`` if given."""
    D = model.data
    if smoothing is None:
        return D
    eps = np.full(len(model.frictions), float(smoothing))
    eps.setflags(write=False)  # same numba type as the model's arrays: no recompilation
    return D._replace(f_eps=eps)


#: the controller blocks listed in the event list (kernel element ``nf + nt + k``, see
#: ``kernels.N_CL_EVENT_BLOCKS``; ``nf + nt + N_CL_EVENT_BLOCKS`` is the controller as a whole):
#: element name and the names of its state codes (``cl_update`` in the kernel)
CONTROLLER_BLOCKS: tuple[tuple[str, dict[int, str] | None], ...] = (
    ("controller.sign", {-1: "-", 0: "unset", 1: "+"}),
    ("controller.saturation", {0: "low", 1: "linear", 2: "high"}),
    ("controller.lookup", None),  # "segment k"
    ("controller.rate_limit", {0: "falling", 1: "tracking", 2: "rising"}),
    (
        "controller.latch",
        {
            int(K.LATCH_ARMED): "armed",
            int(K.LATCH_RAMP): "ramp",
            int(K.LATCH_HELD): "held",
            int(K.LATCH_REARMED): "rearmed",
        },
    ),
)
assert len(CONTROLLER_BLOCKS) == K.N_CL_EVENT_BLOCKS


def _element_mode_name(model: Model, el: int, code: int) -> tuple[str, str]:
    nf = len(model.frictions)
    if el >= nf + len(model.tables):
        k = el - nf - len(model.tables)
        if k >= len(CONTROLLER_BLOCKS):
            return "controller", str(code)
        name, codes = CONTROLLER_BLOCKS[k]
        return name, codes.get(code, str(code)) if codes is not None else f"segment {code}"
    if el < nf:
        fi = model.frictions[el]
        return fi.name, fi.mode_names[code]
    ti = model.tables[el - nf]
    if ti.region_names is not None:
        return ti.name, ti.region_names[code]
    return ti.name, f"segment {code}"


def _events(model: Model, evt: F64, evel: NDArray[np.int64], evf: NDArray[np.int64],
            evto: NDArray[np.int64]) -> tuple[Event, ...]:  # fmt: skip
    """The kernel's event arrays as :class:`Event` s (names looked up once per element and
    mode code: engage-ramp has some 230 events)."""
    names: dict[tuple[int, int], tuple[str, str]] = {}
    out = []
    for te, el, a, b in zip(evt.tolist(), evel.tolist(), evf.tolist(), evto.tolist(), strict=True):
        na = names.get((el, a))
        if na is None:
            na = names[(el, a)] = _element_mode_name(model, el, a)
        nb = names.get((el, b))
        if nb is None:
            nb = names[(el, b)] = _element_mode_name(model, el, b)
        out.append(Event(te, na[0], na[1], nb[1]))
    return tuple(out)


def _check_input_ranges(
    model: Model, sigs: list[Signal], t0: float, t_end: float, *, skip: str | None
) -> None:
    """Raise :class:`InputRangeError` if an input signal leaves the model's range for it on
    [t0, t_end] (``model.input_ranges``; e.g. a throttle above 1 or a pedal outside the actuator
    stroke)."""
    for name, unit, (lo, hi), sig in zip(
        model.input_names, model.input_units, model.input_ranges, sigs, strict=False
    ):
        if name == skip or (lo == -math.inf and hi == math.inf):
            continue
        (vmin, tmin), (vmax, tmax) = sig.extremes(t0, t_end)
        tol = 1e-12 * max([1.0] + [abs(b) for b in (lo, hi) if math.isfinite(b)])
        bad = (vmin, tmin) if vmin < lo - tol else (vmax, tmax) if vmax > hi + tol else None
        if bad is not None:
            u = f" {unit}" if unit and unit != "-" else ""
            raise InputRangeError(
                f"input {name!r} = {bad[0]:.6g}{u} at t = {bad[1]:.6g} s: outside its range "
                f"[{lo:g}, {hi:g}]{u} on this model ({model.chain.name})"
            )


def _raise_non_finite(model: Model, T: F64, Y: F64, nx: int, nxs: int) -> None:
    """Raise ``RuntimeError`` naming the first time and column at which the run went non-finite."""
    rows = np.flatnonzero(~np.isfinite(Y).all(axis=1))
    i = int(rows[0])
    col = int(np.flatnonzero(~np.isfinite(Y[i]))[0])
    if col < nx:
        what = f"state {model.state_names[col]!r}"
    elif col < nxs:
        what = f"controller state {col - nx}"
    elif col == nxs:
        what = "the supplied work"
    else:
        what = f"the dissipated energy of {model.power_names()[col - nxs - 1]!r}"
    raise RuntimeError(
        f"the simulation went non-finite: {what} = {float(Y[i, col])!r} at t = {float(T[i]):.9g} s. "
        "Check the inputs and the initial state for values far outside the physical range."
    )


def _check_times(t: Any, what: str, t0: float, t1: float) -> F64:
    """``t`` as a 1-D float array of finite times within ``[t0, t1]`` [s], or a ValueError
    naming ``what`` and the offending value."""
    try:
        a = np.atleast_1d(np.asarray(t, dtype=float))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} = {t!r}: must be times [s] ({exc})") from None
    if a.ndim != 1 or a.shape[0] == 0:
        raise ValueError(f"{what}: must be a non-empty 1-D array of times [s], got shape {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a) | (a < t0) | (a > t1))
    if bad.shape[0]:
        k = int(bad[0])
        raise ValueError(
            f"{what}[{k}] = {float(a[k])!r} [s]: must be finite and within the run [{t0:g}, {t1:g}] s"
        )
    return np.ascontiguousarray(a)


def _second_law(
    model: Model, action: str, p_min: float, t: float, col: int, p_scale: float
) -> None:
    """Act on the run's most negative dissipated power ``p_min`` [W] (element ``col`` of
    ``model.power_names()``, at ``t`` [s]) if it is clearly negative (below
    ``-SECOND_LAW_RTOL * p_scale - 1e-12`` W)."""
    if action == "ignore" or p_min >= -(SECOND_LAW_RTOL * p_scale + 1e-12):
        return
    msg = (
        f"second law violated: element {model.power_names()[col]!r} dissipates {p_min:.6g} W "
        f"at t = {t:.9g} s (it supplies energy; the run's largest total dissipated power is "
        f"{p_scale:.6g} W). A friction capacity or a damping below zero? "
        "(res.stats['dissipation_min_W'])"
    )
    if action == "raise":
        raise SecondLawError(msg)
    warnings.warn(msg, RuntimeWarning, stacklevel=3)


def _signals_for(model: Model, inputs: Mapping[str, Signal | float]) -> list[Signal]:
    if not isinstance(inputs, Mapping):
        raise TypeError(
            f"inputs = {inputs!r}: must be a mapping input name -> Signal or number "
            f"(the model's inputs: {model.input_names})"
        )
    unknown = set(inputs) - set(model.input_names)
    if unknown:
        raise KeyError(
            f"unknown input(s) {sorted(unknown)}; the model's inputs: {model.input_names}"
        )
    missing = [n for n in model.input_names if n not in inputs]
    if missing:
        raise KeyError(
            f"missing input signal(s) {missing}; the model's inputs: {model.input_names}"
        )
    out = []
    for n in model.input_names:
        s = inputs[n]
        if not isinstance(s, Signal):
            try:
                s = constant(s)  # type: ignore[arg-type]
            except (TypeError, ValueError) as exc:
                raise ValueError(f"input {n!r} = {s!r}: {exc}") from None
        out.append(s)
    return out


def simulate(
    model: Model,
    x0: F64,
    inputs: Mapping[str, Signal | float],
    *,
    t_end: float,
    t0: float = 0.0,
    options: SimulationOptions | None = None,
    raise_on_zeno: bool = True,
    controller: Any = None,
    controller_initial: float = 0.0,
    t_eval: Any = None,
) -> SimulationResult:
    """Simulate ``model`` from state ``x0`` at ``t0`` [s] to ``t_end`` [s] with input signals.

    ``inputs`` maps every input name of the model to a :class:`Signal` (or a constant); with a
    ``controller`` (:class:`~drivetrain_ctrl.control.blocks.Controller`) the input it drives is
    computed in the loop and must not be given; ``controller_initial`` is its initial value (e.g.
    the actuator position [m]). ``t_eval`` [s]: record the run at exactly these times (increasing,
    within ``[t0, t_end]``), from the integrator's continuous extension, instead of at its
    steps (the steps and events are the same). Returns a
    :class:`SimulationResult`; raises :class:`ZenoError` if events accumulate (unless
    ``raise_on_zeno=False``, then the partial result has ``status == 'zeno'``).

    Bad input is rejected before the run, naming the argument: an input signal outside the
    model's range for it (``model.input_ranges``: on the drivetrain throttle in [0, 1], pedal
    within the actuator stroke, brake in [0, brake.capacity_max]) raises
    :class:`InputRangeError` with the value and the time; a run whose state or energies become
    non-finite raises ``RuntimeError`` naming the time and the column.
    """
    if options is None:
        opts = SimulationOptions()
    elif isinstance(options, SimulationOptions):
        opts = options
    else:
        raise TypeError(
            f"options = {options!r}: must be a SimulationOptions (e.g. "
            "SimulationOptions(rtol=1e-9)) or None"
        )
    if not isinstance(raise_on_zeno, bool):
        raise TypeError(f"raise_on_zeno = {raise_on_zeno!r}: must be True or False")
    for nm, v in (("t0", t0), ("t_end", t_end)):
        if not is_finite_real(v):
            raise ValueError(f"{nm} = {v!r}: must be a finite number [s]")
    if controller is not None:
        require_controller(controller, "simulate")
    try:
        x0 = np.array(x0, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"x0 = {x0!r}: must be {model.nx} numbers for states {model.state_names} ({exc})"
        ) from None
    if x0.shape != (model.nx,):
        raise ValueError(
            f"x0 must have shape ({model.nx},) for states {model.state_names}, got {x0.shape}"
        )
    if not np.all(np.isfinite(x0)):
        bad = [model.state_names[i] for i in np.flatnonzero(~np.isfinite(x0))]
        raise ValueError(f"x0 has non-finite values in {bad}")
    if not t_end > t0:
        raise ValueError(f"t_end = {t_end!r} must be > t0 = {t0!r} [s]")
    if t_eval is None:
        t_out = np.zeros(0)
    else:
        t_out = _check_times(t_eval, "t_eval", float(t0), float(t_end))
        if t_out.shape[0] > 1 and not np.all(np.diff(t_out) > 0):
            k = int(np.flatnonzero(np.diff(t_out) <= 0)[0])
            raise ValueError(
                f"t_eval must be strictly increasing: t_eval[{k + 1}] = {float(t_out[k + 1])!r} follows "
                f"{float(t_out[k])!r} [s]"
            )
        if opts.record_every != 1:
            raise ValueError(
                f"SimulationOptions.record_every = {opts.record_every} with t_eval: give one "
                "of them (t_eval records exactly its times)"
            )
    inputs_given = inputs
    if t_end - t0 > opts.max_steps * opts.h_max:
        raise ValueError(
            f"t_end = {t_end!r} s: a run of {t_end - t0:g} s cannot finish within "
            f"SimulationOptions.max_steps = {opts.max_steps} steps of at most h_max = "
            f"{opts.h_max:g} s (raise max_steps or h_max, or shorten the run)"
        )
    driven_input = None
    if controller is not None:
        driven = driven_input = controller.output
        if driven not in model.input_names:
            raise KeyError(
                f"controller output {driven!r} is not an input of the model {model.input_names}"
            )
        if driven in inputs:
            raise KeyError(
                f"input {driven!r} is driven by the controller; do not give a signal for it"
            )
        inputs = {**inputs, driven: 0.0}
    sigs = _signals_for(model, inputs)
    _check_input_ranges(model, sigs, float(t0), float(t_end), skip=driven_input)
    ci = controller_initial
    if controller is None and not (is_finite_real(ci) and ci == 0.0):
        raise ValueError(
            f"controller_initial = {ci!r}: only a closed-loop run (controller=...) uses it"
        )
    if controller is not None:
        if not is_finite_real(ci):
            raise ValueError(f"controller_initial = {ci!r}: must be a finite number")
        lo, hi = model.input_ranges[model.input_names.index(controller.output)]
        if not lo <= ci <= hi:
            raise ValueError(
                f"controller_initial = {ci!r}: outside the range [{lo:g}, {hi:g}] of the "
                f"controlled input {controller.output!r} on this model"
            )
        Cd, cs, refs = controller.compile(model, hold=float(controller_initial))
        y_cl0 = controller.initial_states(model, x0, float(controller_initial))
        sigs = sigs + list(refs)
    else:
        Cd, cs, y_cl0 = K.empty_controller(), np.zeros(K.CS_XD), np.zeros(0)
    S = tuple(pack_signals(sigs))
    bp_set = {b for s in sigs for b in s.breakpoints}
    if controller is not None and controller.start_time is not None:
        bp_set.add(float(controller.start_time))
    bps = sorted(b for b in bp_set if t0 < b < t_end)
    bps_arr = np.array(bps, dtype=float)
    D = _smoothed(model, opts.smoothing)
    announce_compile()
    tic = time.perf_counter()
    out = K.simulate_kernel(
        D,
        S,
        bps_arr,
        x0,
        float(t0),
        float(t_end),
        opts.rtol,
        opts.atol,
        opts.h_max,
        min(opts.h_init, opts.h_max),
        opts.tol_w,
        opts.energy,
        opts.zeno_count,
        opts.zeno_window,
        opts.max_events,
        opts.max_steps,
        Cd,
        cs,
        y_cl0,
        len(model.input_names),
        t_out,
        opts.record_every,
    )
    wall = time.perf_counter() - tic
    (T, Y, U, FM, RG, evt, evel, evf, evto, status, status_el) = out[:11]
    (t_last, nsteps, nrej, nfev, nknee, nincons) = out[11:17]
    (p_min, t_pmin, el_pmin, p_scale) = out[17:]
    nx = model.nx
    nu = len(model.input_names)
    nxs = nx + y_cl0.shape[0]
    if T.shape[0] and not np.isfinite(Y[-1]).all():
        _raise_non_finite(model, T, Y, nx, nxs)
    events = _events(model, evt, evel, evf, evto)
    stat = _STATUS.get(int(status), str(status))
    res = SimulationResult(
        model=model,
        t=T,
        x=Y[:, :nx],
        u=np.ascontiguousarray(U[:, :nu]),
        fm=FM,
        reg=RG,
        events=events,
        work_in=Y[:, nxs] if opts.energy else None,
        dissipated=Y[:, nxs + 1 :] if opts.energy else None,
        status=stat,
        stats={
            "steps": int(nsteps),
            "rejected": int(nrej),
            "nfev": int(nfev),
            "knee_crossings": int(nknee),
            # decisions where no mode combination was consistent (least inconsistent taken)
            "inconsistent_decisions": int(nincons),
            "wall_time_s": wall,
            "t0": float(t0),
            "t_last": float(t_last),
            # second law: the most negative dissipated power of any element at the accepted
            # steps' ends [W] (nan without energy integration)
            "dissipation_min_W": float(p_min) if opts.energy and el_pmin >= 0 else math.nan,
        },
        extras={"controller_states": Y[:, nx:nxs], "controller_command": U[:, nu]}
        if controller is not None
        else {},
        smoothing=opts.smoothing,
        rerun=functools.partial(
            simulate,
            model,
            x0,
            inputs_given,
            t_end=t_end,
            t0=t0,
            options=dataclasses.replace(opts, record_every=1),
            raise_on_zeno=raise_on_zeno,
            controller=controller,
            controller_initial=controller_initial,
        ),
    )
    if opts.energy and el_pmin >= 0:
        _second_law(model, opts.second_law, float(p_min), float(t_pmin), int(el_pmin), p_scale)
    if stat == "zeno" and raise_on_zeno:
        name = _element_mode_name(model, int(status_el), 0)[0] if status_el >= 0 else "?"
        raise ZenoError(
            f"events accumulate (Zeno) at t = {float(t_last):.9g} s on element {name!r}: "
            f"{opts.zeno_count} events (mode changes or guard crossings) within "
            f"{opts.zeno_window:g} s"
        )
    if stat == "too_many_candidates":
        raise RuntimeError(
            f"simulation stopped at t = {float(t_last):.9g} s: more than "
            f"{K.DM_MAX_CANDIDATES} friction elements are at zero relative speed (within "
            f"tol_w = {opts.tol_w:g}) at once; deciding them together would try 3^n stuck/slip "
            "combinations. Start from a state with fewer elements at rest relative to each "
            "other, or give fewer friction elements."
        )
    if stat not in ("ok", "zeno"):
        hint = {
            "step_too_small": "the step size fell below 1e-14 s (a state changing too fast: "
            "check the initial state and the inputs for values far outside the physical range)",
            "max_steps": f"SimulationOptions.max_steps = {opts.max_steps} steps taken before "
            f"t_end = {float(t_end):g} s (raise max_steps, or shorten the run)",
            "max_events": f"SimulationOptions.max_events = {opts.max_events} events before "
            f"t_end = {float(t_end):g} s (raise max_events, or shorten the run)",
        }.get(stat, stat)
        raise RuntimeError(f"simulation stopped at t = {float(t_last):.9g} s: {hint}")
    if nincons > 0:
        warnings.warn(
            f"{int(nincons)} mode decision(s) found no consistent stuck/slip combination (or "
            "guards still fired after 20 re-checks); the least inconsistent one was taken. "
            "The trajectory may be wrong near those events: check the model's capacities and "
            "inputs, or lower tol_w (res.stats['inconsistent_decisions']).",
            RuntimeWarning,
            stacklevel=2,
        )
    return res
