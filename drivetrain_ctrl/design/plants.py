"""Plants, plant sets and frequency grids: the shared input of every design tool.

A design works on one SISO plant or a set of them (the same controller must serve every
operating point and parameter vertex). A :class:`Plant` is any python-control LTI system
(``StateSpace`` or ``TransferFunction``, continuous ``dt = 0`` or discrete ``dt > 0``) with an
optional input delay in seconds. The delay is applied **exactly** in the frequency response
(a factor ``exp(-j w delay)``), so a design checked on the grid sees the true phase lag; a
rational approximation (:meth:`Plant.with_pade`) is only formed where a state-space model is
needed (closed-loop poles, time responses, H-infinity synthesis).

:func:`frequency_grid` chooses a log-spaced grid in rad/s from the plants' poles and zeros (and,
for sampled plants, up to the Nyquist frequency ``pi / dt``), denser around an expected crossover
and around lightly damped poles/zeros. :func:`as_plant_set` turns whatever the user passes (an
LTI, a :class:`Plant`, a list of them, a :class:`PlantSet`) into a :class:`PlantSet`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, overload

import control
import numpy as np

from drivetrain_ctrl.core.validate import real_number

__all__ = ["Plant", "PlantSet", "as_plant_set", "frequency_grid"]

# Damping ratio below which a pole/zero pair gets extra grid points around its frequency.
_LIGHT_DAMPING = 0.3


def _check_lti(name: str, sys: object) -> None:
    """Raise if ``sys`` is not a SISO python-control LTI system with a usable timebase."""
    if not isinstance(sys, control.LTI):
        raise TypeError(
            f"{name} = {sys!r}: must be a python-control LTI system (StateSpace or "
            "TransferFunction)"
        )
    if sys.ninputs != 1 or sys.noutputs != 1:
        raise ValueError(
            f"{name}: must be SISO (1 input, 1 output), got {sys.ninputs} inputs and "
            f"{sys.noutputs} outputs; pick a channel, e.g. sys[0, 0]"
        )
    if sys.dt is True:
        raise ValueError(
            f"{name}.dt = True: a discrete plant needs its sample period in seconds "
            "(e.g. control.tf(num, den, 0.01))"
        )
    if sys.dt is not None and not isinstance(sys.dt, bool):
        real_number(f"{name}.dt", sys.dt, lo=0.0, unit="s")


@dataclass(frozen=True)
class Plant:
    """One SISO plant for design: an LTI system with an exact input delay.

    ``sys``: a python-control ``StateSpace`` or ``TransferFunction``, SISO, continuous
    (``dt = 0`` or ``None``) or discrete (``dt > 0`` seconds). ``delay``: input (dead-time)
    delay [s], applied exactly in :meth:`freqresp`; for a discrete plant it need not be a multiple
    of ``dt`` there (only :meth:`with_pade` needs that). ``name``: a label used in reports (which
    operating point, which vertex).
    """

    sys: control.LTI
    delay: float = 0.0
    name: str = ""

    def __post_init__(self) -> None:
        _check_lti("Plant.sys", self.sys)
        d = real_number("Plant.delay", self.delay, lo=0.0, unit="s")
        object.__setattr__(self, "delay", d)
        if not isinstance(self.name, str):
            raise TypeError(f"Plant.name = {self.name!r}: must be a string")

    @property
    def dt(self) -> float:
        """Sample period [s]; 0.0 for a continuous plant."""
        return 0.0 if self.sys.dt is None else float(self.sys.dt)

    @property
    def is_discrete(self) -> bool:
        """True for a sampled plant (``dt > 0``)."""
        return self.dt > 0.0

    def freqresp(self, w: Any) -> np.ndarray:
        """Complex frequency response ``P(jw) exp(-jw delay)`` at the angular frequencies ``w``
        [rad/s] (a 1-D array or a scalar; returns the same shape). For a discrete plant
        ``P(exp(jw dt)) exp(-jw delay)``. A pole on the imaginary axis (an integrator at
        ``w = 0``) gives an infinite value there rather than an error."""
        wa = np.asarray(w, dtype=float)
        if wa.ndim > 1:
            raise ValueError(f"w: must be a scalar or a 1-D array, got shape {wa.shape}")
        if not np.all(np.isfinite(wa)):
            raise ValueError(f"w = {w!r}: every frequency must be finite [rad/s]")
        flat = np.atleast_1d(wa)
        x = np.exp(1j * flat * self.dt) if self.is_discrete else 1j * flat
        with np.errstate(divide="ignore", invalid="ignore"):
            resp = np.asarray(self.sys(x, warn_infinite=False), dtype=complex).reshape(flat.shape)
        resp = np.where(np.isfinite(resp), resp, complex(np.inf, 0.0))
        if self.delay:
            resp = resp * np.exp(-1j * flat * self.delay)
        return resp if wa.ndim else resp[0]

    def with_pade(self, order: int = 3) -> control.LTI:
        """A rational model of the plant with its delay, where a state-space model is needed.

        Continuous: ``sys`` times an ``order``-th order Pade approximation of
        ``exp(-s delay)`` (python-control ``pade``); accurate in phase up to roughly
        ``w delay ~ order``. Discrete: the delay as ``z^-k``, exact, which requires the delay to
        be a multiple ``k dt`` of the sample period. Returns ``sys`` unchanged when there is no
        delay, and keeps its type (``StateSpace`` stays ``StateSpace``).
        """
        if isinstance(order, bool) or not isinstance(order, int | np.integer) or order < 1:
            raise ValueError(f"order = {order!r}: must be an integer >= 1")
        if not self.delay:
            return self.sys
        if self.is_discrete:
            k = self.delay / self.dt
            if abs(k - round(k)) > 1e-9 * max(1.0, k):
                raise ValueError(
                    f"Plant.delay = {self.delay!r} s is not a multiple of the sample period "
                    f"dt = {self.dt!r} s ({k:.6g} samples); a discrete rational model needs "
                    "delay = k dt (the frequency response uses the delay exactly anyway)"
                )
            den = [1.0] + [0.0] * round(k)
            d_lti: control.LTI = control.tf([1.0], den, self.dt)
        else:
            num, den = control.pade(self.delay, int(order))
            d_lti = control.tf(num, den)
        if isinstance(self.sys, control.StateSpace):
            d_lti = control.ss(d_lti)
        return self.sys * d_lti

    def poles_zeros(self) -> tuple[np.ndarray, np.ndarray]:
        """The poles and zeros of ``sys`` (complex arrays; s-plane or z-plane)."""
        return np.asarray(control.poles(self.sys)), np.asarray(control.zeros(self.sys))


@dataclass(frozen=True)
class PlantSet:
    """A non-empty, ordered set of :class:`Plant` s that one controller must serve.

    Build it with :func:`as_plant_set` (which also names unnamed plants ``plant 0``, ...).
    Indexing returns a :class:`Plant` (or a :class:`PlantSet` for a slice); ``len`` and
    iteration work as for a tuple.
    """

    plants: tuple[Plant, ...]

    def __post_init__(self) -> None:
        plants = tuple(self.plants)
        if not plants:
            raise ValueError("PlantSet.plants = (): needs at least one plant")
        for i, p in enumerate(plants):
            if not isinstance(p, Plant):
                raise TypeError(
                    f"PlantSet.plants[{i}] = {p!r}: must be a Plant (use as_plant_set to "
                    "wrap LTI systems)"
                )
        object.__setattr__(self, "plants", plants)

    def freqresp(self, w: Any) -> np.ndarray:
        """Frequency responses of every plant, shape ``(n_plants, n_w)`` complex, at ``w``
        [rad/s] (delays exact; see :meth:`Plant.freqresp`)."""
        wa = np.atleast_1d(np.asarray(w, dtype=float))
        return np.stack([p.freqresp(wa) for p in self.plants])

    @property
    def names(self) -> tuple[str, ...]:
        """The plants' names, in order."""
        return tuple(p.name for p in self.plants)

    @property
    def dt(self) -> float:
        """The common sample period [s] (0.0 if every plant is continuous). Raises if the set
        mixes continuous and discrete plants or different sample periods."""
        dts = {p.dt for p in self.plants}
        if len(dts) > 1:
            listing = ", ".join(f"{p.name or i!s}: dt = {p.dt:g}" for i, p in enumerate(self))
            raise ValueError(
                f"the plant set mixes sample periods ({listing}); a controller needs one "
                "timebase: sample every plant with the same dt"
            )
        return dts.pop()

    def __len__(self) -> int:
        return len(self.plants)

    def __iter__(self) -> Iterator[Plant]:
        return iter(self.plants)

    @overload
    def __getitem__(self, i: int) -> Plant: ...
    @overload
    def __getitem__(self, i: slice) -> PlantSet: ...
    def __getitem__(self, i: int | slice) -> Plant | PlantSet:
        if isinstance(i, slice):
            return PlantSet(self.plants[i])
        return self.plants[i]


def _plants_of(p: object, delay: float | None, where: str) -> list[Plant]:
    if isinstance(p, PlantSet):
        items: Sequence[object] = p.plants
    elif isinstance(p, Plant | control.LTI):
        items = [p]
    elif isinstance(p, list | tuple):
        items = p
    else:
        raise TypeError(
            f"{where} = {p!r}: must be a python-control LTI system, a Plant, a PlantSet or a "
            "list/tuple of them"
        )
    out: list[Plant] = []
    for i, item in enumerate(items):
        label = where if len(items) == 1 and not isinstance(p, list | tuple) else f"{where}[{i}]"
        if isinstance(item, Plant):
            if delay is not None and item.delay != delay:
                raise ValueError(
                    f"{label}: a Plant with delay = {item.delay!r} s was given together with "
                    f"delay = {delay!r} s; set the delay on the Plant or pass bare LTI systems"
                )
            out.append(item)
        elif isinstance(item, PlantSet):
            out.extend(_plants_of(item, delay, label))
        elif isinstance(item, control.LTI):
            _check_lti(label, item)
            out.append(Plant(item, 0.0 if delay is None else delay))
        else:
            raise TypeError(
                f"{label} = {item!r}: must be a python-control LTI system, a Plant or a PlantSet"
            )
    return out


def as_plant_set(p: object, *, delay: float | None = None) -> PlantSet:
    """``p`` as a :class:`PlantSet`: an LTI system, a :class:`Plant`, a :class:`PlantSet` or a
    list/tuple of them (nested sets are flattened, in order).

    ``delay`` [s] is given to every bare LTI system (a :class:`Plant` keeps its own delay; giving
    a different ``delay`` with one is an error rather than a silent override). Unnamed plants are
    named by position, ``plant 0``, ``plant 1``, ... so that reports can say which plant limits a
    design.
    """
    if delay is not None:
        delay = real_number("delay", delay, lo=0.0, unit="s")
    if isinstance(p, PlantSet) and delay is None:
        plants = list(p.plants)
    else:
        plants = _plants_of(p, delay, "plants")
    if not plants:
        raise ValueError(f"plants = {p!r}: needs at least one plant")
    named = [
        pl if pl.name else dataclasses.replace(pl, name=f"plant {i}") for i, pl in enumerate(plants)
    ]
    return PlantSet(tuple(named))


def _features(plant: Plant) -> tuple[list[float], list[tuple[float, float]]]:
    """Characteristic frequencies [rad/s] of a plant (nonzero pole/zero magnitudes, mapped from
    the z-plane for a discrete plant, and ``1/delay``) and its lightly damped (wn, zeta) pairs."""
    poles, zeros = plant.poles_zeros()
    roots = np.concatenate([poles, zeros])
    roots = roots[np.isfinite(roots)]
    if plant.is_discrete:
        roots = roots[np.abs(roots) > 1e-12]  # z = 0: a pure delay, no frequency
        roots = np.log(roots.astype(complex)) / plant.dt
    mags = np.abs(roots)
    keep = mags > 1e-9 * max(1.0, float(mags.max()) if mags.size else 1.0)
    feats = [float(m) for m in mags[keep]]
    light = []
    for r, m in zip(roots[keep], mags[keep], strict=True):
        zeta = -float(r.real) / float(m)
        if abs(r.imag) > 0 and abs(zeta) < _LIGHT_DAMPING:
            light.append((float(m), abs(zeta)))
    if plant.delay:
        feats.append(1.0 / plant.delay)
    return feats, light


def frequency_grid(
    plants: object,
    *,
    n: int = 200,
    w_min: float | None = None,
    w_max: float | None = None,
    crossover: float | None = None,
) -> np.ndarray:
    """A sorted, log-spaced angular-frequency grid [rad/s] for designing on ``plants``.

    ``plants``: anything :func:`as_plant_set` accepts. The range, unless given, spans two decades
    below the slowest and two above the fastest characteristic frequency of the set (nonzero
    pole and zero magnitudes, the z-plane ones mapped by ``|ln z| / dt``, ``1/delay``, and
    ``crossover``; 1 rad/s if there is none); with a discrete plant the grid ends exactly at the
    smallest Nyquist frequency ``pi / dt`` (the response above it is aliased). ``n`` points are
    spaced logarithmically over the range; with ``crossover`` [rad/s] a further ``n // 4`` points
    fill ``[crossover / 3, 3 crossover]``, and every lightly damped pole/zero pair (damping
    < 0.3) gets 8 points across its resonance peak, so that a margin or a sensitivity peak is not
    missed between samples. The result is strictly increasing (duplicates removed).
    """
    pset = as_plant_set(plants)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 2:
        raise ValueError(f"n = {n!r}: must be an integer >= 2 (number of grid points)")
    if crossover is not None:
        crossover = real_number("crossover", crossover, lo=0.0, lo_open=True, unit="rad/s")
    feats: list[float] = []
    light: list[tuple[float, float]] = []
    for p in pset:
        f, lt = _features(p)
        feats += f
        light += lt
    if crossover is not None:
        feats.append(crossover)
    if not feats:
        feats = [1.0]
    nyq = [math.pi / p.dt for p in pset if p.is_discrete]
    w_nyq = min(nyq) if nyq else math.inf
    lo = min(feats) / 100.0 if w_min is None else None
    hi = (w_nyq if nyq else max(feats) * 100.0) if w_max is None else None
    if w_min is not None:
        lo = real_number("w_min", w_min, lo=0.0, lo_open=True, unit="rad/s")
    if w_max is not None:
        hi = real_number("w_max", w_max, lo=0.0, lo_open=True, unit="rad/s")
        if hi > w_nyq * (1 + 1e-12):
            raise ValueError(
                f"w_max = {w_max!r} rad/s: must be <= the Nyquist frequency pi/dt = "
                f"{w_nyq:.6g} rad/s of the discrete plants (the response above it is aliased)"
            )
    assert lo is not None and hi is not None
    lo = min(lo, hi / 10.0) if w_min is None else lo  # a degenerate automatic range: one decade
    if not lo < hi:
        raise ValueError(f"w_min = {lo!r} rad/s must be < w_max = {hi!r} rad/s")
    parts = [np.logspace(math.log10(lo), math.log10(hi), int(n))]
    if crossover is not None:
        a, b = max(lo, crossover / 3.0), min(hi, crossover * 3.0)
        if a < b:
            parts.append(np.logspace(math.log10(a), math.log10(b), max(int(n) // 4, 2)))
    for wn, zeta in light:
        half = max(3.0 * zeta, 0.01) * wn
        a, b = max(lo, wn - half), min(hi, wn + half)
        if a < b:
            parts.append(np.linspace(a, b, 8))
    grid = np.unique(np.clip(np.concatenate([*parts, [lo, hi]]), lo, hi))
    keep = np.concatenate([[True], np.diff(grid) > 1e-12 * grid[1:]])  # round-off duplicates
    grid = grid[keep]
    grid[0], grid[-1] = lo, hi  # exact ends (w_nyq itself for a discrete set)
    return grid
