"""Input signals with known breakpoints: piecewise-linear tables, steps, ramps, sines and sums.

A :class:`Signal` is a piecewise-linear (PWL) part plus a sum of sines. The PWL part is a list of
knots ``(t_k, v_k)`` with non-decreasing times; two knots at the same time make a jump
(right-continuous: the value *at* the jump time is the later one). Before the first knot the
value is the first value, after the last knot the last value. The breakpoints (knot times, sine
start times) are known, so the simulator stops exactly at each of them and never integrates across
a kink or a jump.

Units are whatever the consuming input expects (SI inside: throttle [-], pedal [m], brake
capacity [N m]). Time is in seconds.

Examples
--------
>>> from drivetrain_ctrl.core.signals import step, ramp, constant
>>> u = constant(0.2) + step(1.0, 0.3)          # 0.2, then 0.5 from t = 1 s
>>> float(u(0.5)), float(u(1.0))
(0.2, 0.5)
>>> r = ramp(0.5, 2.5, 0.11, 0.03)               # 0.11 m -> 0.03 m between 0.5 s and 2.5 s
>>> float(r(1.5))
0.07
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .validate import real_number

__all__ = [
    "Signal",
    "SignalArrays",
    "constant",
    "step",
    "ramp",
    "table",
    "sine",
    "pack_signals",
]


def _check_finite(name: str, value: float) -> float:
    """``value`` as a float (:func:`~drivetrain_ctrl.core.validate.real_number`): TypeError
    unless a real number, ValueError unless finite."""
    return real_number(name, value, type_error=TypeError, phrasing="got")


@dataclass(frozen=True, slots=True)
class Sine:
    """``amplitude * sin(omega * (t - t_start) + phase)`` for ``t >= t_start``, 0 before.

    amplitude in the signal's unit, omega [rad/s], phase [rad], t_start [s].
    """

    amplitude: float
    omega: float
    phase: float = 0.0
    t_start: float = 0.0

    def __post_init__(self) -> None:
        for name in ("amplitude", "omega", "phase", "t_start"):
            _check_finite(f"Sine.{name}", getattr(self, name))

    def __call__(self, t: NDArray[np.float64] | float) -> NDArray[np.float64]:
        tt = np.asarray(t, dtype=float)
        out = self.amplitude * np.sin(self.omega * (tt - self.t_start) + self.phase)
        return np.where(tt >= self.t_start, out, 0.0)


@dataclass(frozen=True, slots=True)
class Signal:
    """A piecewise-linear signal plus a sum of sines, with known breakpoints.

    Build with :func:`constant`, :func:`step`, :func:`ramp`, :func:`table`, :func:`sine`, and
    combine with ``+`` (and ``-`` / scalar ``*``). Evaluate with ``signal(t)``.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]
    sines: tuple[Sine, ...] = ()

    def __post_init__(self) -> None:
        for nm in ("times", "values", "sines"):
            if not isinstance(getattr(self, nm), tuple):
                raise TypeError(
                    f"Signal.{nm} = {getattr(self, nm)!r}: must be a tuple (build signals with "
                    "constant, step, ramp, table, sine)"
                )
        for i, sw in enumerate(self.sines):
            if not isinstance(sw, Sine):
                raise TypeError(f"Signal.sines[{i}] = {sw!r}: must be a Sine")
        if len(self.times) != len(self.values) or len(self.times) == 0:
            raise ValueError(
                f"Signal: times and values must be non-empty and of equal length, got "
                f"{len(self.times)} times and {len(self.values)} values"
            )
        for i, t in enumerate(self.times):
            _check_finite(f"Signal.times[{i}]", t)
        for i, v in enumerate(self.values):
            _check_finite(f"Signal.values[{i}]", v)
        for i in range(1, len(self.times)):
            if self.times[i] < self.times[i - 1]:
                raise ValueError(
                    f"Signal.times must be non-decreasing, but times[{i}]={self.times[i]} < "
                    f"times[{i - 1}]={self.times[i - 1]}"
                )
            if i >= 2 and self.times[i] == self.times[i - 1] == self.times[i - 2]:
                raise ValueError(f"Signal.times: more than two knots at t={self.times[i]}")

    # -- evaluation -------------------------------------------------------------------------
    def pwl(self, t: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Right-continuous value of the piecewise-linear part at ``t`` [s]."""
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        out = _eval_pwl_many(np.asarray(self.times), np.asarray(self.values), tt)
        return out if np.ndim(t) else out[:1].reshape(())

    def __call__(self, t: NDArray[np.float64] | float) -> NDArray[np.float64]:
        out = self.pwl(t)
        for s in self.sines:
            out = out + s(t)
        return out

    def left_limit(self, t: float) -> float:
        """Value just before ``t`` [s] (differs from ``self(t)`` at a jump)."""
        ts, vs = np.asarray(self.times), np.asarray(self.values)
        k = int(np.searchsorted(ts, t, side="left")) - 1
        if k < 0:
            v = float(vs[0])
        else:
            v = _eval_pwl(ts, vs, t, ts[k])
        return v + float(sum(float(s(t)) for s in self.sines if t > s.t_start))

    def extremes(self, t0: float, t1: float) -> tuple[tuple[float, float], tuple[float, float]]:
        """``((v_min, t_min), (v_max, t_max))``: the smallest and largest value on ``[t0, t1]`` [s]
        and where they occur. Exact for the piecewise-linear part (its extremes lie at ``t0``,
        ``t1`` or a knot, both sides of a jump counted); with sines, on a grid of 40 points per
        period of the fastest one (at most 200000 points) plus those times. Of equal values the
        earliest time is given."""
        t0, t1 = _check_finite("extremes: t0", t0), _check_finite("extremes: t1", t1)
        if not t0 <= t1:
            raise ValueError(f"extremes: t0 = {t0!r} s must be <= t1 = {t1!r} s")
        ts, vs = np.asarray(self.times), np.asarray(self.values)
        inside = (ts > t0) & (ts < t1)
        cand_t = np.concatenate([[t0, t1, t1], ts[inside]])
        cand_v = np.concatenate(
            [
                [_eval_pwl(ts, vs, t0, t0), self.left_limit_pwl(t1), _eval_pwl(ts, vs, t1, t1)],
                vs[inside],
            ]
        )
        if self.sines:
            w = max(abs(s.omega) for s in self.sines)
            n = int(min(200_000, max(100.0, 40.0 * (t1 - t0) * w / (2.0 * math.pi))))
            grid = np.linspace(t0, t1, n)
            # np.interp takes one side of a jump: the candidates above carry both
            cand_t = np.concatenate([cand_t, grid])
            cand_v = np.concatenate([cand_v, np.interp(grid, ts, vs)])
            for sw in self.sines:
                cand_v = cand_v + sw(cand_t)
        order = np.argsort(cand_t, kind="stable")  # the earliest time of a tie
        tv, vv = cand_t[order], cand_v[order]
        i_min, i_max = int(np.argmin(vv)), int(np.argmax(vv))
        return (float(vv[i_min]), float(tv[i_min])), (float(vv[i_max]), float(tv[i_max]))

    @property
    def breakpoints(self) -> tuple[float, ...]:
        """Sorted unique times at which the signal or its slope may jump [s]."""
        bps = set(self.times) | {s.t_start for s in self.sines}
        return tuple(sorted(bps))

    # -- algebra -----------------------------------------------------------------------------
    def __add__(self, other: Signal | float) -> Signal:
        if not isinstance(other, Signal):
            other = constant(_check_finite("constant", other))
        grid = sorted(set(self.times) | set(other.times))
        ts: list[float] = []
        vs: list[float] = []
        for t in grid:
            left = self.left_limit_pwl(t) + other.left_limit_pwl(t)
            right = float(self.pwl(t)) + float(other.pwl(t))
            if left != right:
                ts += [t, t]
                vs += [left, right]
            else:
                ts.append(t)
                vs.append(right)
        return Signal(tuple(ts), tuple(vs), self.sines + other.sines)

    __radd__ = __add__

    def __mul__(self, k: float) -> Signal:
        k = _check_finite("scale", k)
        return Signal(
            self.times,
            tuple(k * v for v in self.values),
            tuple(Sine(k * s.amplitude, s.omega, s.phase, s.t_start) for s in self.sines),
        )

    __rmul__ = __mul__

    def __neg__(self) -> Signal:
        return self * -1.0

    def __sub__(self, other: Signal | float) -> Signal:
        return self + (-other if isinstance(other, Signal) else -_check_finite("constant", other))

    def left_limit_pwl(self, t: float) -> float:
        """Left limit of the piecewise-linear part at ``t`` [s]."""
        ts, vs = np.asarray(self.times), np.asarray(self.values)
        k = int(np.searchsorted(ts, t, side="left")) - 1
        if k < 0:
            return float(vs[0])
        return _eval_pwl(ts, vs, t, ts[k])

    # -- serialisation ---------------------------------------------------------------------
    def to_dict(self) -> dict[str, object]:
        """Plain-data form (for TOML scenario files)."""
        d: dict[str, object] = {"times": list(self.times), "values": list(self.values)}
        if self.sines:
            d["sines"] = [
                {"amplitude": s.amplitude, "omega": s.omega, "phase": s.phase, "t_start": s.t_start}
                for s in self.sines
            ]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, object], *, name: str = "signal") -> Signal:
        """Inverse of :meth:`to_dict`; unknown keys raise ``ValueError`` naming them."""
        if not isinstance(d, Mapping):
            raise ValueError(
                f"{name} = {d!r}: must be a table with 'times' and 'values' (lists of numbers) "
                "and optionally 'sines' (an array of tables)"
            )
        allowed = {"times", "values", "sines"}
        unknown = set(d) - allowed
        if unknown:
            raise ValueError(f"{name}: unknown key(s) {sorted(unknown)}; allowed {sorted(allowed)}")
        if "times" not in d or "values" not in d:
            raise ValueError(f"{name}: needs both 'times' and 'values'")
        sines = []
        raw = d.get("sines", [])
        if not isinstance(raw, (list, tuple)) or not all(isinstance(s, Mapping) for s in raw):
            raise ValueError(
                f"{name}.sines = {raw!r}: must be an array of tables, each with amplitude, omega "
                f"and optionally phase, t_start (TOML: [[{name}.sines]])"
            )
        raw_sines: list[Mapping[str, object]] = list(raw)
        for i, s in enumerate(raw_sines):
            unknown = set(s) - {"amplitude", "omega", "phase", "t_start"}
            if unknown:
                raise ValueError(f"{name}.sines[{i}]: unknown key(s) {sorted(unknown)}")
            for key in ("amplitude", "omega"):
                if key not in s:
                    raise ValueError(f"{name}.sines[{i}].{key}: missing")
            try:
                sines.append(Sine(**{k: _check_finite(k, v) for k, v in s.items()}))  # type: ignore[arg-type]
            except (TypeError, ValueError) as exc:
                raise ValueError(f"{name}.sines[{i}]: {exc}") from exc
        vals: dict[str, tuple[float, ...]] = {}
        for key in ("times", "values"):
            seq = d[key]
            if not isinstance(seq, (list, tuple)):
                raise ValueError(f"{name}.{key} = {seq!r}: must be a list of numbers")
            try:
                vals[key] = tuple(_check_finite(f"{name}.{key}[{i}]", v) for i, v in enumerate(seq))
            except (TypeError, ValueError) as exc:
                raise ValueError(str(exc)) from exc
        try:
            return cls(vals["times"], vals["values"], tuple(sines))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name}: {exc}") from exc


def _eval_pwl(ts: NDArray[np.float64], vs: NDArray[np.float64], t: float, t_ref: float) -> float:
    """Value at ``t`` of the linear piece that is active at ``t_ref`` (right-continuous)."""
    n = ts.shape[0]
    k = int(np.searchsorted(ts, t_ref, side="right")) - 1
    if k < 0:
        return float(vs[0])
    if k >= n - 1:
        return float(vs[n - 1])
    t0, t1 = ts[k], ts[k + 1]
    if t1 <= t0:
        return float(vs[k + 1])
    return float(vs[k] + (vs[k + 1] - vs[k]) * (t - t0) / (t1 - t0))


def _eval_pwl_many(
    ts: NDArray[np.float64], vs: NDArray[np.float64], t: NDArray[np.float64]
) -> NDArray[np.float64]:
    """:func:`_eval_pwl` at every element of ``t`` (each on its own piece), in one pass: the
    same formula, element by element."""
    n = ts.shape[0]
    k = np.searchsorted(ts, t, side="right") - 1
    out = np.empty(t.shape, dtype=float)
    before = k < 0
    after = k >= n - 1
    out[before] = vs[0]
    out[after] = vs[n - 1]
    mid = ~(before | after)
    if np.any(mid):
        km = k[mid]
        t0, t1 = ts[km], ts[km + 1]
        v0, v1 = vs[km], vs[km + 1]
        jump = t1 <= t0
        with np.errstate(divide="ignore", invalid="ignore"):
            lin = v0 + (v1 - v0) * (t[mid] - t0) / (t1 - t0)
        out[mid] = np.where(jump, v1, lin)
    return out


def constant(value: float) -> Signal:
    """A constant signal."""
    return Signal((0.0,), (_check_finite("value", value),))


def step(t_step: float, height: float, *, initial: float = 0.0) -> Signal:
    """``initial`` before ``t_step`` [s], ``initial + height`` from ``t_step`` on."""
    t = _check_finite("t_step", t_step)
    a = _check_finite("initial", initial)
    return Signal((t, t), (a, a + _check_finite("height", height)))


def ramp(t_start: float, t_end: float, v_start: float, v_end: float) -> Signal:
    """``v_start`` until ``t_start``, linear to ``v_end`` at ``t_end``, then constant."""
    t0, t1 = _check_finite("t_start", t_start), _check_finite("t_end", t_end)
    if not t1 > t0:
        raise ValueError(f"ramp: t_end={t1} must be > t_start={t0}")
    return Signal((t0, t1), (_check_finite("v_start", v_start), _check_finite("v_end", v_end)))


def table(times: Sequence[float], values: Sequence[float]) -> Signal:
    """Piecewise-linear table; repeat a time to make a jump."""
    for nm, seq in (("times", times), ("values", values)):
        if isinstance(seq, (str, bytes)) or not isinstance(seq, Iterable):
            raise TypeError(f"table: {nm} = {seq!r}: must be a sequence of numbers")
    return Signal(
        tuple(_check_finite(f"table: times[{i}]", t) for i, t in enumerate(times)),
        tuple(_check_finite(f"table: values[{i}]", v) for i, v in enumerate(values)),
    )


def sine(amplitude: float, omega: float, *, phase: float = 0.0, t_start: float = 0.0) -> Signal:
    """``amplitude * sin(omega (t - t_start) + phase)`` from ``t_start`` [s] on; omega [rad/s]."""
    s = Sine(
        _check_finite("amplitude", amplitude),
        _check_finite("omega", omega),
        _check_finite("phase", phase),
        _check_finite("t_start", t_start),
    )
    return Signal((0.0,), (0.0,), (s,))


class SignalArrays(NamedTuple):
    """Padded array form of several signals for the compiled kernels.

    ``t[i, :nk[i]]``, ``v[i, :nk[i]]`` are the knots of signal ``i``; ``sin[i, :ns[i], :]`` rows
    are (amplitude, omega, phase, t_start).
    """

    t: NDArray[np.float64]
    v: NDArray[np.float64]
    nk: NDArray[np.int64]
    sin: NDArray[np.float64]
    ns: NDArray[np.int64]


def pack_signals(signals: Iterable[Signal]) -> SignalArrays:
    """Pack signals into :class:`SignalArrays` (one row per signal)."""
    sigs = list(signals)
    n = len(sigs)
    mk = max([len(s.times) for s in sigs] + [1])
    ms = max([len(s.sines) for s in sigs] + [1])
    t = np.zeros((n, mk))
    v = np.zeros((n, mk))
    nk = np.zeros(n, dtype=np.int64)
    sn = np.zeros((n, ms, 4))
    ns = np.zeros(n, dtype=np.int64)
    for i, s in enumerate(sigs):
        k = len(s.times)
        t[i, :k] = s.times
        v[i, :k] = s.values
        nk[i] = k
        for j, sw in enumerate(s.sines):
            sn[i, j] = (sw.amplitude, sw.omega, sw.phase, sw.t_start)
        ns[i] = len(s.sines)
    return SignalArrays(t, v, nk, sn, ns)
