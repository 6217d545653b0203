"""A compiled chain model: modes, dynamics, guards, stuck torques, energy and POG form.

:class:`Model` is immutable: it holds the :class:`~drivetrain_ctrl.plant.chain.Chain` it was made from
and its array form (:class:`~drivetrain_ctrl.kernels.ChainData`). The state it runs on is passed
in (a state vector ``x``, an input vector ``u`` and a :class:`Mode`); the simulator is separate.

Modes are first-class: every friction element has the modes ``stuck`` / ``slip+`` / ``slip-`` /
``open`` (renamed per element, e.g. the tyre's ``grip``), every spring with backlash the modes
``contact-`` / ``gap`` / ``contact+``, and every piecewise-linear table a region index (its knees
are breakpoints). For each combination the model gives the dynamics in POG form, the analytic
Jacobian, the stuck torques and the guards.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from .. import kernels as K
from ..core.tables import _pwl_clamped
from ..core.validate import is_finite_real
from .chain import BACKLASH_MODES, Chain, Friction, Spring

__all__ = ["Model", "Mode", "PogForm", "TableInfo", "FrictionInfo"]

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Mode:
    """Discrete state: friction modes ``fm`` (kernel codes) and table regions ``reg``."""

    fm: tuple[int, ...]
    reg: tuple[int, ...]

    def __post_init__(self) -> None:
        for nm in ("fm", "reg"):
            v = getattr(self, nm)
            if not isinstance(v, (tuple, list, np.ndarray)) or not all(
                isinstance(c, (int, np.integer)) and not isinstance(c, (bool, np.bool_)) for c in v
            ):
                raise TypeError(f"Mode.{nm} = {v!r}: must be a tuple of integer codes")
            if not isinstance(v, tuple) or not all(type(c) is int for c in v):
                object.__setattr__(self, nm, tuple(int(c) for c in v))  # hashable, plain ints

    def arrays(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        return np.array(self.fm, dtype=np.int64), np.array(self.reg, dtype=np.int64)


@dataclass(frozen=True, slots=True)
class FrictionInfo:
    """A friction element: its name, mode names and where it sits."""

    name: str
    mode_names: tuple[str, str, str, str]
    kind: str  # "coupling" | "ground"
    index: int
    constant_capacity: bool


@dataclass(frozen=True, slots=True)
class TableInfo:
    """A piecewise-linear characteristic: its name, argument, bounds and (backlash) mode names."""

    name: str
    arg: str
    bounds: tuple[float, ...]
    region_names: tuple[str, ...] | None  # backlash modes per region, or None


@dataclass(frozen=True)
class PogForm:
    """Dynamics of one mode in POG form ``L z' = A z + B u + g(z, u)``.

    ``T`` maps the reduced coordinates of the mode to the full state, ``x = T z`` (its speed
    block is a basis of the speeds allowed by the stuck elements: the congruent transformation of
    the paper, eq. (3), with the stuck relative speeds removed). ``L = T^T diag(M, I) T``.
    """

    L: F64
    A: F64
    B: F64
    T: F64
    model: Model = field(repr=False)
    mode: Mode = field(repr=False)

    def g(self, z: F64, u: F64) -> F64:
        """The smooth nonlinear remainder ``g(z, u) = L z' - A z - B u``."""
        x = self.T @ z
        xdot = self.model.rhs(x, u, self.mode)
        Lfull = self.model._mass_matrix()
        return self.T.T @ (Lfull @ xdot) - self.A @ z - self.B @ u


def _pwl_spring(sp: Spring) -> tuple[list[float], list[float], list[float], list[str] | None]:
    """Bounds, slopes, offsets (and backlash region names) of an odd spring with backlash."""
    g = sp.backlash
    xs, ys = sp.x, sp.y
    pos_b: list[float] = []
    pos_s: list[float] = []
    pos_o: list[float] = []
    for k in range(len(xs) - 1):
        s = (ys[k + 1] - ys[k]) / (xs[k + 1] - xs[k])
        # torque = ys[k] + s (q - g - xs[k]) on [g + xs[k], g + xs[k+1]]
        pos_s.append(s)
        pos_o.append(ys[k] - s * (g + xs[k]))
        if k < len(xs) - 2:
            pos_b.append(g + xs[k + 1])
    # negative side: odd mirror, torque(q) = -torque(-q) -> slope s, offset -o
    neg_b = [-b for b in reversed(pos_b)]
    neg_s = list(reversed(pos_s))
    neg_o = [-o for o in reversed(pos_o)]
    if g > 0.0:
        bounds = neg_b + [-g, g] + pos_b
        slopes = neg_s + [0.0] + pos_s
        offs = neg_o + [0.0] + pos_o
        nneg = len(neg_s)
        names = [BACKLASH_MODES[0]] * nneg + [BACKLASH_MODES[1]] + [BACKLASH_MODES[2]] * len(pos_s)
        return bounds, slopes, offs, names
    # no gap: the first piece is shared by both sides (through the origin, offset 0)
    bounds = neg_b + pos_b
    slopes = neg_s[:-1] + pos_s
    offs = neg_o[:-1] + pos_o
    return bounds, slopes, offs, None


def _energy_constants(bounds: list[float], slopes: list[float], offs: list[float]) -> list[float]:
    """Constants ``e_r`` so that ``V = s q^2/2 + o q + e_r`` is continuous with ``V(0) = 0``."""
    nr = len(slopes)
    e = [0.0] * nr
    r0 = 0
    while r0 < len(bounds) and 0.0 > bounds[r0]:
        r0 += 1
    for r in range(r0 + 1, nr):
        b = bounds[r - 1]
        e[r] = (0.5 * slopes[r - 1] * b * b + offs[r - 1] * b + e[r - 1]) - (
            0.5 * slopes[r] * b * b + offs[r] * b
        )
    for r in range(r0 - 1, -1, -1):
        b = bounds[r]
        e[r] = (0.5 * slopes[r + 1] * b * b + offs[r + 1] * b + e[r + 1]) - (
            0.5 * slopes[r] * b * b + offs[r] * b
        )
    return e


class Model:
    """Immutable compiled model of a :class:`Chain`.

    Attributes: ``chain``, ``data`` (:class:`~drivetrain_ctrl.kernels.ChainData`),
    ``state_names``, ``state_units``, ``input_names``, ``input_units`` (``""`` where the chain
    gives none), ``input_ranges`` (``(lo, hi)`` per input, ``(-inf, inf)`` where the chain gives
    none), ``frictions``, ``tables``.
    """

    __slots__ = (
        "chain",
        "data",
        "state_names",
        "state_units",
        "input_names",
        "input_units",
        "input_ranges",
        "frictions",
        "tables",
        "_frozen",
    )

    def __init__(self, chain: Chain) -> None:
        if not isinstance(chain, Chain):
            raise TypeError(f"Model(chain = {chain!r}): must be a Chain")
        self.chain = chain
        bodies, couplings = chain.bodies, chain.couplings
        n, m = len(bodies), len(couplings)
        inputs = list(chain.inputs)
        uidx = {name: i for i, name in enumerate(inputs)}
        names: list[str] = []
        units: list[str] = []
        for b in bodies:
            rot = b.kind == "rotational"
            names.append(f"omega_{b.name}" if rot else f"v_{b.name}")
            units.append("rad/s" if rot else "m/s")
        c_q = [-1] * m
        for c, cp in enumerate(couplings):
            if cp.spring is not None:
                c_q[c] = len(names)
                names.append(f"q_{cp.name}")
                units.append("rad" if bodies[c].kind == "rotational" else "m")
        b_pos = [-1] * n
        for i, b in enumerate(bodies):
            if b.tracks_position:
                b_pos[i] = len(names)
                names.append(f"pos_{b.name}")
                units.append("rad" if b.kind == "rotational" else "m")
        l_x: list[int] = []
        for s in chain.sources:
            l_x.append(len(names))
            names.append(f"lag_{s.name}")
            units.append("-")
        nx = len(names)

        # tables: (kind, idx, bounds, slopes, offs, econst, info)
        tabs: list[tuple[int, int, list[float], list[float], list[float], list[float]]] = []
        infos: list[TableInfo] = []

        def add_table(kind: int, idx: int, pieces: tuple, name: str, arg: str, rn=None) -> int:  # type: ignore[type-arg]
            bnds, sl, of = pieces
            ec = _energy_constants(bnds, sl, of) if kind == K.ARG_TWIST else [0.0] * len(sl)
            tabs.append((kind, idx, bnds, sl, of, ec))
            infos.append(TableInfo(name, arg, tuple(bnds), tuple(rn) if rn else None))
            return len(tabs) - 1

        c_table = [-1] * m
        c_gap = [-1] * m  # the spring region in which a contact-only damper is off: the gap
        for c, cp in enumerate(couplings):
            if cp.spring is not None:
                b_, s_, o_, rn = _pwl_spring(cp.spring)
                nm = cp.name if cp.spring.backlash > 0 else f"{cp.name}.spring"
                c_table[c] = add_table(K.ARG_TWIST, c, (b_, s_, o_), nm, names[c_q[c]], rn)
                if not cp.damper_in_gap:
                    assert rn is not None  # Coupling: damper_in_gap=False needs a backlash
                    c_gap[c] = rn.index(BACKLASH_MODES[1])

        frictions: list[tuple[str, int, int, Friction]] = []
        for c, cp in enumerate(couplings):
            if cp.friction is not None:
                frictions.append((cp.friction.name, 0, c, cp.friction))
        for i, b in enumerate(bodies):
            if b.ground_friction is not None:
                frictions.append((b.ground_friction.name, 1, i, b.ground_friction))
        nf = len(frictions)
        f_table = [-1] * nf
        f_mu = [-1] * nf
        f_uidx = [-1] * nf
        finfo: list[FrictionInfo] = []
        for f, (nm, kind, idx, fr) in enumerate(frictions):
            if fr.capacity_input is not None:
                f_uidx[f] = uidx[fr.capacity_input]
            if fr.capacity_table is not None:
                f_table[f] = add_table(
                    K.ARG_INPUT,
                    f_uidx[f],
                    _pwl_clamped(fr.capacity_table),
                    f"{nm}.capacity_table",
                    str(fr.capacity_input),
                )
            if fr.mu_table is not None and len(fr.mu_table.x) > 1:
                # its argument |w| is >= 0 and the table starts at 0: no bound there (a region
                # below 0 would be entered, and left at once, at every return to zero slip)
                bnds, sl, of = _pwl_clamped(fr.mu_table)
                f_mu[f] = add_table(
                    K.ARG_SLIP, f, (bnds[1:], sl[1:], of[1:]), f"{nm}.mu_table", f"|w_{nm}|"
                )
            finfo.append(
                FrictionInfo(
                    nm,
                    fr.mode_names,
                    "coupling" if kind == 0 else "ground",
                    idx,
                    fr.capacity_input is None,
                )
            )
        l_table = [-1] * len(chain.sources)
        for j, s in enumerate(chain.sources):
            if s.gain_table is not None:
                bi = chain.body_index(s.body)
                l_table[j] = add_table(
                    K.ARG_SPEED, bi, _pwl_clamped(s.gain_table), f"{s.name}.gain_table", names[bi]
                )

        nt = len(tabs)
        maxb = max([len(t[2]) for t in tabs] + [1])
        t_b = np.full((nt, maxb), np.inf)
        t_s = np.zeros((nt, maxb + 1))
        t_o = np.zeros((nt, maxb + 1))
        t_e = np.zeros((nt, maxb + 1))
        for k, (_, _, bnds, sl, of, ec) in enumerate(tabs):
            t_b[k, : len(bnds)] = bnds
            t_s[k, : len(sl)] = sl
            t_o[k, : len(of)] = of
            t_e[k, : len(ec)] = ec

        def i64(a: list[int]) -> NDArray[np.int64]:
            return np.array(a, dtype=np.int64).reshape(-1)

        def f64(a: list[float]) -> F64:
            return np.array(a, dtype=np.float64).reshape(-1)

        self.data = K.ChainData(
            M=f64([b.inertia for b in bodies]),
            visc=f64([b.viscous for b in bodies]),
            quad=f64([b.quadratic for b in bodies]),
            load=f64([b.load for b in bodies]),
            b_uidx=i64([uidx[b.torque_input] if b.torque_input else -1 for b in bodies]),
            b_ugain=f64([b.input_gain for b in bodies]),
            b_pos=i64(b_pos),
            ratio=f64([c.ratio for c in couplings]),
            damp=f64([c.damper for c in couplings]),
            c_table=i64(c_table),
            c_q=i64(c_q),
            c_gap=i64(c_gap),
            f_kind=i64([fr[1] for fr in frictions]),
            f_idx=i64([fr[2] for fr in frictions]),
            f_scale=f64([fr[3].scale for fr in frictions]),
            f_uidx=i64(f_uidx),
            f_table=i64(f_table),
            f_static=f64([fr[3].static_ratio for fr in frictions]),
            f_mu=i64(f_mu),
            f_eps=np.zeros(nf),
            t_nb=i64([len(t[2]) for t in tabs]),
            t_b=t_b,
            t_s=t_s,
            t_o=t_o,
            t_e=t_e,
            t_kind=i64([t[0] for t in tabs]),
            t_idx=i64([t[1] for t in tabs]),
            l_body=i64([chain.body_index(s.body) for s in chain.sources]),
            l_uidx=i64([uidx[s.input] for s in chain.sources]),
            l_tau=f64([s.tau for s in chain.sources]),
            l_gain=f64([s.gain for s in chain.sources]),
            l_table=i64(l_table),
            l_x=i64(l_x),
            nx=nx,
        )
        for arr in self.data[:-1]:
            arr.setflags(write=False)
        self.state_names = tuple(names)
        self.state_units = tuple(units)
        self.input_names = tuple(inputs)
        self.input_units = tuple(chain.input_units.get(n, "") for n in inputs)
        self.input_ranges = tuple(
            (float(r[0]), float(r[1]))
            if (r := chain.input_ranges.get(n))
            else (-math.inf, math.inf)
            for n in inputs
        )
        self.frictions = tuple(finfo)
        self.tables = tuple(infos)
        self._frozen = True

    def __setattr__(self, key: str, value: object) -> None:
        if getattr(self, "_frozen", False):
            raise AttributeError(f"Model is immutable; cannot set {key!r}")
        object.__setattr__(self, key, value)

    def __delattr__(self, key: str) -> None:
        raise AttributeError(f"Model is immutable; cannot delete {key!r}")

    # -- sizes and names -----------------------------------------------------------------------
    @property
    def nx(self) -> int:
        """Number of states."""
        return int(self.data.nx)

    @property
    def n_bodies(self) -> int:
        return int(self.data.M.shape[0])

    def state_index(self, name: str) -> int:
        """Index of state ``name`` (e.g. ``"omega_engine"``)."""
        try:
            return self.state_names.index(name)
        except ValueError:
            raise KeyError(f"no state {name!r}; states: {self.state_names}") from None

    def friction_index(self, name: str) -> int:
        for f, fi in enumerate(self.frictions):
            if fi.name == name:
                return f
        raise KeyError(
            f"no friction element {name!r}; elements: {[f.name for f in self.frictions]}"
        )

    def friction(self, element: int | str) -> Friction:
        """The chain's :class:`Friction` element at index ``element`` (as in :attr:`frictions`)
        or of that name."""
        f = self.friction_index(element) if isinstance(element, str) else int(element)
        fi = self.frictions[f]
        if fi.kind == "coupling":
            fr = self.chain.couplings[fi.index].friction
        else:
            fr = self.chain.bodies[fi.index].ground_friction
        assert fr is not None
        return fr

    def capacity(self, element: int | str, u: F64, mode: Mode | None = None) -> float:
        """Kinetic capacity at zero slip [N m or N] of friction ``element`` (index or name) at
        inputs ``u``, the value the kernels use: :meth:`Friction.capacity` of its capacity input,
        in the table region held by ``mode`` (None: the region of the input's value). For the
        clutch, k12(x_c) (paper, eq. (1); k13(x_c), eq. (5)). Over samples:
        ``model.friction(element).capacity(values of its input)``."""
        f = self.friction_index(element) if isinstance(element, str) else int(element)
        fr = self.friction(f)
        if fr.capacity_input is None:
            return fr.capacity(0.0)
        v = float(u[self.input_names.index(fr.capacity_input)])
        kt = int(self.data.f_table[f])
        return fr.capacity(v, None if mode is None or kt < 0 else mode.reg[kt])

    def inputs(self, **values: float) -> F64:
        """Input vector from keyword values; every input must be given (a finite number), unknown
        names rejected. (The simulator checks the physical ranges, :attr:`input_ranges`.)"""
        unknown = set(values) - set(self.input_names)
        if unknown:
            raise KeyError(f"unknown input(s) {sorted(unknown)}; inputs: {self.input_names}")
        missing = [n for n in self.input_names if n not in values]
        if missing:
            raise KeyError(f"missing input(s) {missing}")
        for n in self.input_names:
            if not is_finite_real(values[n]):
                raise ValueError(f"input {n} = {values[n]!r}: must be a finite number")
        return np.array([float(values[n]) for n in self.input_names])

    def check_mode(self, mode: Mode) -> None:
        """Raise if ``mode`` is not a mode of this model: a :class:`Mode` with one code per
        friction element (0..3) and one region per table (within the table's pieces)."""
        if not isinstance(mode, Mode):
            raise TypeError(f"mode = {mode!r}: must be a Mode (e.g. from Model.decide)")
        if len(mode.fm) != len(self.frictions):
            raise ValueError(
                f"Mode.fm has {len(mode.fm)} codes for {len(self.frictions)} friction elements "
                f"{[f.name for f in self.frictions]}"
            )
        if len(mode.reg) != len(self.tables):
            raise ValueError(
                f"Mode.reg has {len(mode.reg)} regions for {len(self.tables)} tables "
                f"{[t.name for t in self.tables]}"
            )
        for fi, c in zip(self.frictions, mode.fm, strict=True):
            if not 0 <= c <= 3:
                raise ValueError(f"Mode.fm code {c} for {fi.name!r}: must be 0..3 {fi.mode_names}")
        for k, (ti, r) in enumerate(zip(self.tables, mode.reg, strict=True)):
            n_pieces = int(self.data.t_nb[k]) + 1
            if not 0 <= r < n_pieces:
                raise ValueError(
                    f"Mode.reg[{k}] = {r} for table {ti.name!r}: must be 0..{n_pieces - 1}"
                )

    def _check_x(self, x: object) -> F64:
        xa = np.asarray(x, dtype=float)
        if xa.shape != (self.nx,):
            raise ValueError(f"state x must have shape ({self.nx},), got {xa.shape}")
        return xa

    def _check_u(self, u: object) -> F64:
        ua = np.asarray(u, dtype=float)
        if ua.shape != (len(self.input_names),):
            raise ValueError(f"inputs u must have shape ({len(self.input_names)},), got {ua.shape}")
        return ua

    def _mass_matrix(self) -> F64:
        d = np.ones(self.nx)
        d[: self.n_bodies] = self.data.M
        return np.diag(d)

    # -- modes -----------------------------------------------------------------------------------
    def mode_names(self, mode: Mode) -> dict[str, str]:
        """Named modes of every friction element and every backlash (``{element: mode}``)."""
        self.check_mode(mode)
        out = {fi.name: fi.mode_names[c] for fi, c in zip(self.frictions, mode.fm, strict=True)}
        for ti, r in zip(self.tables, mode.reg, strict=True):
            if ti.region_names is not None:
                out[ti.name] = ti.region_names[r]
        return out

    def decide(self, x: F64, u: F64, *, tol: float = 1e-9) -> tuple[Mode, F64]:
        """Consistent mode at state ``x`` and inputs ``u`` (and ``x`` projected onto it)."""
        x = self._check_x(x).copy()
        ua = self._check_u(u)
        if not (is_finite_real(tol) and tol > 0):
            raise ValueError(f"decide: tol = {tol!r} [rad/s or m/s]: must be a finite number > 0")
        fm = np.full(len(self.frictions), K.OPEN, dtype=np.int64)
        reg = np.zeros(len(self.tables), dtype=np.int64)
        r = K.decide_modes(self.data, x, ua, fm, reg, float(tol))
        if r == K.DM_TOO_MANY:
            raise ValueError(
                f"more than {K.DM_MAX_CANDIDATES} friction elements are at zero relative speed "
                f"(within tol = {tol:g}) at once: deciding them together would try 3^n "
                "stuck/slip combinations"
            )
        return Mode(tuple(int(v) for v in fm), tuple(int(v) for v in reg)), x

    def mode_from_state(self, x: F64, u: F64, friction_modes: Mapping[str, str]) -> Mode:
        """Mode with the given friction mode names (others: by the sign of their speed) and the
        table regions of ``x``, ``u``."""
        x = self._check_x(x)
        u = self._check_u(u)
        fm = np.zeros(len(self.frictions), dtype=np.int64)
        unknown = set(friction_modes) - {f.name for f in self.frictions}
        if unknown:
            raise KeyError(f"unknown friction element(s) {sorted(unknown)}")
        for f, fi in enumerate(self.frictions):
            if fi.name in friction_modes:
                nm = friction_modes[fi.name]
                if nm not in fi.mode_names:
                    raise ValueError(f"{fi.name}: mode {nm!r} not in {fi.mode_names}")
                fm[f] = fi.mode_names.index(nm)
            else:
                w = K.rel_speed(self.data, f, np.asarray(x, dtype=float))
                fm[f] = K.SLIP_POS if w >= 0 else K.SLIP_NEG
        reg = np.zeros(len(self.tables), dtype=np.int64)
        K.update_regions(self.data, np.asarray(x, float), np.asarray(u, float), reg)
        return Mode(tuple(int(v) for v in fm), tuple(int(v) for v in reg))

    def friction_mode_combinations(self) -> Iterator[tuple[int, ...]]:
        """Every combination of friction modes (``open`` only where capacity can be zero)."""
        choices = []
        for fi in self.frictions:
            c = [K.STUCK, K.SLIP_POS, K.SLIP_NEG]
            if not fi.constant_capacity:
                c.append(K.OPEN)
            choices.append(c)
        yield from itertools.product(*choices)

    # -- dynamics --------------------------------------------------------------------------------
    def _arrays(
        self, x: F64, u: F64, mode: Mode
    ) -> tuple[F64, F64, NDArray[np.int64], NDArray[np.int64]]:
        x = self._check_x(x)
        u = self._check_u(u)
        self.check_mode(mode)
        fm, reg = mode.arrays()
        return x, u, fm, reg

    def rhs(self, x: F64, u: F64, mode: Mode) -> F64:
        """State derivative in ``mode`` (SI units per :attr:`state_units` per second)."""
        x, u, fm, reg = self._arrays(x, u, mode)
        P, _ = K.mode_matrices(self.data, fm)
        out = np.zeros(self.nx)
        K.rhs(self.data, x, u, fm, reg, P, out)
        return out

    def jacobian(self, x: F64, u: F64, mode: Mode) -> tuple[F64, F64]:
        """Analytic ``(d xdot/dx, d xdot/du)`` inside ``mode`` (speeds constrained by it)."""
        x, u, fm, reg = self._arrays(x, u, mode)
        P, _ = K.mode_matrices(self.data, fm)
        return K.jacobians(self.data, x, u, fm, reg, P, False)

    def stuck_torques(self, x: F64, u: F64, mode: Mode) -> dict[str, float]:
        """Torque [N m] (force [N]) each stuck friction element carries."""
        x, u, fm, reg = self._arrays(x, u, mode)
        _, Lam = K.mode_matrices(self.data, fm)
        lam = K.stuck_torques(self.data, x, u, fm, reg, Lam)
        return {fi.name: float(lam[f]) for f, fi in enumerate(self.frictions) if fm[f] == K.STUCK}

    def guards(self, x: F64, u: F64, mode: Mode) -> F64:
        """Guard values (all >= 0 while ``mode`` holds); layout as in :func:`kernels.guards`."""
        x, u, fm, reg = self._arrays(x, u, mode)
        _, Lam = K.mode_matrices(self.data, fm)
        g = np.zeros(K.n_guards(self.data))
        K.guards(self.data, x, u, fm, reg, Lam, g)
        return g

    def guard_names(self) -> tuple[str, ...]:
        """Name of every guard, in the layout of :meth:`guards`."""
        out = [f.name for f in self.frictions]
        for t in self.tables:
            out += [f"{t.name}.lower", f"{t.name}.upper"]
        return tuple(out)

    # -- energy ----------------------------------------------------------------------------------
    def stored_energy(self, x: F64) -> float:
        """Stored energy [J]: kinetic + elastic (springs, damper, backlash) + potential (slope)."""
        return float(K.stored_energy(self.data, self._check_x(x)))

    def power_names(self) -> tuple[str, ...]:
        """Names of the dissipation terms returned by :meth:`powers`."""
        return (
            tuple(f"{b.name}.ground" for b in self.chain.bodies)
            + tuple(f"{c.name}.damper" for c in self.chain.couplings)
            + tuple(f.name for f in self.frictions)
        )

    def powers(self, x: F64, u: F64, mode: Mode) -> tuple[float, dict[str, float]]:
        """Power supplied [W] and power dissipated by each element [W] (a coupling's damper: 0
        in its backlash gap if it acts only in contact, ``Coupling.damper_in_gap`` False)."""
        x, u, fm, reg = self._arrays(x, u, mode)
        _, Lam = K.mode_matrices(self.data, fm)
        p_in, pd = K.powers(self.data, x, u, fm, reg, Lam)
        return float(p_in), dict(zip(self.power_names(), (float(v) for v in pd), strict=True))

    # -- POG form ----------------------------------------------------------------------------------
    def speed_basis(self, mode: Mode) -> F64:
        """Basis ``N`` (n, n - k) of the speeds allowed by the stuck elements (``omega = N zeta``)."""
        self.check_mode(mode)
        fm = np.array(mode.fm, dtype=np.int64)
        which = (fm == K.STUCK).astype(np.int64)
        G = K.constraint_rows(self.data, fm, which)
        if G.shape[0] == 0:
            return np.eye(self.n_bodies)
        return np.asarray(scipy.linalg.null_space(G))

    def pog_form(self, mode: Mode, x: F64, u: F64) -> PogForm:
        """POG form of ``mode`` (regions of the piecewise-linear laws taken from ``mode``).

        ``x``, ``u`` only fix the point for the parts of ``A``/``B`` that depend on the region.
        """
        x, u, fm, reg = self._arrays(x, u, mode)
        n = self.n_bodies
        N = self.speed_basis(mode)
        T = np.zeros((self.nx, N.shape[1] + self.nx - n))
        T[:n, : N.shape[1]] = N
        T[n:, N.shape[1] :] = np.eye(self.nx - n)
        Minv = np.diag(1.0 / self.data.M)
        Jlin, Blin = K.jacobians(self.data, x, u, fm, reg, Minv, True)
        Lfull = self._mass_matrix()
        # unconstrained linear part in full coordinates: Lfull xdot = Lfull (Jlin x + Blin u)
        A = T.T @ Lfull @ Jlin @ T
        B = T.T @ Lfull @ Blin
        L = T.T @ Lfull @ T
        return PogForm(L=L, A=A, B=B, T=T, model=self, mode=mode)
