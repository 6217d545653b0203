"""Figures (the only module of the package that imports matplotlib).

:func:`plot_simulation` draws an overview of a simulation run (speeds, coupling torques, inputs,
a strip chart of the modes of every friction element and backlash, event markers);
:func:`plot_energy` the energy balance; :func:`plot_engagement` clutch starts in the layout of the
paper's Fig. 14; :func:`plot_loop`, :func:`plot_nyquist` and :func:`plot_root_locus` the loop
analysis (:mod:`drivetrain_ctrl.linear.margins`); :func:`report_figures`, :func:`pdf_pages` and
:func:`write_report_pdf` the controller report. All build a
:class:`matplotlib.figure.Figure` directly (no pyplot, so no GUI backend, no global figure registry
and nothing to close) and save it as PNG if a path is given. In Jupyter the returned figure
displays itself; elsewhere use ``fig.savefig(...)``.

Engineering units appear here only (rpm, km/h, mm); speeds of the driveline are referred to the
gearbox primary shaft so that they can be compared on one axis.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..core.units import RPM_TO_RAD_S
from ..core.validate import is_finite_real
from ..plant.model import Model
from ..sim.simulator import SimulationResult

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "plot_simulation",
    "plot_energy",
    "plot_engagement",
    "plot_loop",
    "plot_nyquist",
    "plot_root_locus",
    "report_figures",
    "pdf_pages",
    "write_report_pdf",
    "DPI",
]

F64 = NDArray[np.float64]

#: resolution of saved PNGs [dots per inch]
DPI: int = 120

# colours of the mode codes: stuck, slip+, slip-, open (backlash: contact-, gap, contact+ mapped)
_MODE_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d9d9d9")
_MODE_LABELS = (
    "stuck / grip / holding / standstill",
    "slip+ / moving+ / contact+",
    "slip- / moving- / contact-",
    "open / released / free / gap",
)


def _new_figure(nrows: int, height_ratios: list[float], size: tuple[float, float]) -> Figure:
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    fig.subplots(nrows, 1, sharex=True, gridspec_kw={"height_ratios": height_ratios})
    return fig


def _save(fig: Figure, path: str | Path | None) -> None:
    """Save ``fig`` as a PNG to ``path`` (which must end in ``.png``; None: do not save)."""
    if path is None:
        return
    if not isinstance(path, (str, Path)) or Path(path).suffix.lower() != ".png":
        raise ValueError(f"path = {path!r}: give a file name ending in .png")
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=DPI, format="png")


def _to_primary_factor(model: Model, body: int, primary: int) -> float:
    """Factor turning the speed of ``body`` into the speed of ``primary`` it corresponds to
    with no slip and no twist (the product of the ratios between them)."""
    r = model.data.ratio
    if body >= primary:
        return float(np.prod(r[primary:body]))
    return float(1.0 / np.prod(r[body:primary]))


def _primary_index(model: Model) -> int:
    names = [b.name for b in model.chain.bodies]
    if "primary" in names:
        return names.index("primary")
    return min(1, len(names) - 1)


def _runs(codes: NDArray[Any]) -> list[tuple[int, int, int]]:
    """Runs ``(start, stop, code)`` of equal values (sample ``stop`` starts the next run)."""
    out = []
    n = len(codes)
    start = 0
    for i in range(1, n + 1):
        if i == n or codes[i] != codes[start]:
            out.append((start, i, int(codes[start])))
            start = i
    return out


def _lockup(res: SimulationResult) -> float | None:
    try:
        return res.lockup_time("clutch")
    except KeyError:
        return None


def _mark_lockup(axes: list[Axes], t_lock: float | None) -> None:
    if t_lock is None:
        return
    for ax in axes:
        ax.axvline(t_lock, color="k", ls=":", lw=1.0)


def _clutch_capacity(model: Model, u: F64) -> F64 | None:
    """Kinetic clutch capacity at zero slip [N m] at the samples (None if no such element)."""
    try:
        fr = model.friction("clutch")
    except KeyError:
        return None
    if fr.capacity_input is None:
        return np.full(u.shape[0], fr.capacity(0.0))
    return fr.capacity(np.asarray(u[:, model.input_names.index(fr.capacity_input)], dtype=float))


def plot_simulation(
    res: SimulationResult,
    path: str | Path | None = None,
    *,
    scenario: str | None = None,
    controller: str | None = None,
    reference: Any = None,
    control_start: float | None = None,
) -> Figure:
    """Overview of run ``res``; saved as PNG (``DPI``) to ``path`` if given. Returns the figure.

    Panels: (1) speeds [rpm] of the engine, the clutch disc / primary shaft and the wheels and
    vehicle referred to the primary shaft (right axis: vehicle speed [km/h] for the same no-slip
    primary speed), and the engine-speed reference of a closed-loop run; (2) coupling torques
    [N m] referred to the primary shaft: clutch (with its capacity, dashed), damper, gear mesh /
    lumped shaft (``backlash``), half-shafts (``axle``); (3) inputs: throttle [-], clutch pedal
    [mm] and, in closed loop, the controller's command x_r [mm] (the pedal is the actuator's
    response to it), service brake [N m]; (4) a strip chart of the mode of every friction element
    and backlash over time, with a tick at each of its events. A dotted vertical line marks the
    final clutch lock-up, a dash-dotted one the controller's start.

    ``scenario`` and ``controller`` (names) head the title; ``reference``: the engine-speed
    reference omega_r(t) [rad/s] (a :class:`~drivetrain_ctrl.core.signals.Signal`), drawn from
    ``control_start`` [s] on (the controller's start; None: the whole run).
    """
    if reference is not None and not callable(reference):
        raise ValueError(
            f"plot_simulation: reference = {reference!r}: a Signal (omega_r(t) [rad/s]) or None"
        )
    if control_start is not None and not is_finite_real(control_start):
        raise ValueError(f"plot_simulation: control_start = {control_start!r}: a time [s] or None")
    model = res.model
    t = res.t
    bodies = [b.name for b in model.chain.bodies]
    # a smoothed run's friction elements have no stick/slip modes: only its backlash in the strip
    moded: list[tuple[str, NDArray[Any], bool]] = (
        [(fi.name, res.fm[:, f], False) for f, fi in enumerate(model.frictions)]
        if res.smoothing is None
        else []
    )
    for k, ti in enumerate(model.tables):
        if ti.region_names is not None:
            moded.append((ti.name, res.reg[:, k], True))
    strip_h = 0.35 * max(len(moded), 1) + 0.4
    fig = _new_figure(4, [3.0, 3.0, 1.8, strip_h], (11.0, 10.0 + 0.3 * len(moded)))
    ax_w, ax_T, ax_u, ax_m = fig.axes
    ip = _primary_index(model)
    head = ", ".join(x for x in (scenario, f"controller {controller}" if controller else None) if x)
    title = (f"{head}\n" if head else "") + (
        f"{model.chain.name}: status {res.status}, {len(res.events)} events"
    )
    if res.smoothing is not None:
        title += f", friction smoothed (tanh, {res.smoothing:g})"
    t_lock = _lockup(res)
    if t_lock is not None:
        title += f", clutch lock-up at {t_lock:.3f} s"
    fig.suptitle(title)

    # (1) speeds
    # (label, colour, line style, width, z-order): the engine on top, visible when locked
    styles = {
        "engine": ("engine", "C3", "-", 1.2, 4),
        "disc": ("clutch disc", "C1", "--", 1.3, 3),
        "primary": ("primary shaft", "C0", "-", 2.2, 2),
        "hub": ("wheels (at primary)", "C2", "-", 1.3, 3),
        "vehicle": ("vehicle (at primary)", "C4", ":", 1.5, 3),
    }
    drivetrain = any(b.name in styles for b in model.chain.bodies)
    for i, b in enumerate(model.chain.bodies):
        if drivetrain and b.name in styles:
            label, col, ls, lw, z = styles[b.name]
            w = res.x[:, i] * _to_primary_factor(model, i, ip) / RPM_TO_RAD_S
            ax_w.plot(t, w, color=col, ls=ls, lw=lw, zorder=z, label=label)
        elif not drivetrain and b.kind == "rotational":
            # a general chain: every rotational body in its own frame
            ax_w.plot(t, res.x[:, i] / RPM_TO_RAD_S, lw=1.3, label=b.name)
    if reference is not None:
        names = [b.name for b in model.chain.bodies]
        ie = names.index("engine") if "engine" in names else 0
        t_r = t if control_start is None else t[t >= control_start]
        w_r = np.asarray(reference(t_r), dtype=float) * _to_primary_factor(model, ie, ip)
        ax_w.plot(t_r, w_r / RPM_TO_RAD_S, color="k", ls="--", lw=1.1, zorder=5,
                  label="engine reference omega_r")  # fmt: skip
    ax_w.set_ylabel("speed [rpm]\n(primary-shaft frame)" if drivetrain else "speed [rpm]")
    ax_w.legend(loc="best", fontsize=8, ncol=2)
    if "vehicle" in bodies:
        f_v = _to_primary_factor(model, bodies.index("vehicle"), ip)  # (rad/s) per (m/s)
        kmh_per_rpm = RPM_TO_RAD_S / f_v * 3.6

        def fwd(x: Any) -> Any:
            return x * kmh_per_rpm

        def inv(x: Any) -> Any:
            return x / kmh_per_rpm

        sec = ax_w.secondary_yaxis("right", functions=(fwd, inv))
        sec.set_ylabel("vehicle speed [km/h]")

    # (2) coupling torques, primary frame
    T = res.coupling_torques()
    labels = {
        "clutch": ("clutch", "C3"),
        "damper": ("damper", "C1"),
        "backlash": ("gear mesh / shaft", "C0"),
        "axle": ("half-shafts", "C2"),
    }
    for c, cp in enumerate(model.chain.couplings):
        if cp.name not in labels:
            continue
        label, col = labels[cp.name]
        # torque in the frame of body c; referred to the primary shaft: divide by the speed factor
        fac = _to_primary_factor(model, c, ip)
        ax_T.plot(t, T[:, c] / fac, color=col, lw=1.2, label=label)
    cap = _clutch_capacity(model, res.u)
    if cap is not None:
        ax_T.plot(t, cap, color="C3", ls="--", lw=0.8, alpha=0.7, label="clutch capacity")
    ax_T.axhline(0.0, color="0.5", lw=0.5)
    ax_T.set_ylabel("torque [N m]\n(primary-shaft frame)")
    ax_T.legend(loc="best", fontsize=8, ncol=2)

    # (3) inputs
    inputs = list(model.input_names)
    handles = []
    if "throttle" in inputs:
        handles += ax_u.plot(t, res.u[:, inputs.index("throttle")], color="C3", label="throttle")
    ax_u.set_ylabel("throttle [-]")
    ax_u.set_ylim(-0.05, 1.05)
    if "pedal" in inputs:
        ax_p = ax_u.twinx()
        cmd = res.extras.get("controller_command")
        handles += ax_p.plot(
            t,
            1e3 * res.u[:, inputs.index("pedal")],
            color="C0",
            label="clutch pedal" if cmd is None else "clutch pedal x_c (actuator)",
        )
        if cmd is not None:
            handles += ax_p.plot(
                t, 1e3 * np.asarray(cmd), color="k", ls="--", lw=1.0,
                label="controller command x_r",
            )  # fmt: skip
        ax_p.set_ylabel("pedal [mm]")
    if "brake" in inputs and np.any(res.u[:, inputs.index("brake")] != 0.0):
        ax_b = ax_u.twinx()
        ax_b.spines["right"].set_position(("axes", 1.08))
        handles += ax_b.plot(t, res.u[:, inputs.index("brake")], color="C2", ls="--", label="brake")
        ax_b.set_ylabel("brake [N m]")
    for j, nm in enumerate(inputs):
        if nm not in ("throttle", "pedal", "brake"):
            handles += ax_u.plot(t, res.u[:, j], label=nm)
    if handles:
        ax_u.legend(handles=handles, loc="best", fontsize=8)

    # (4) mode strip chart with event ticks
    t_hi = float(t[-1])
    for row, (name, codes, is_backlash) in enumerate(moded):
        y = len(moded) - 1 - row
        for start, stop, code in _runs(codes):
            t0 = float(t[start])
            t1 = float(t[stop]) if stop < len(t) else t_hi
            if is_backlash:
                rn = model.tables[[ti.name for ti in model.tables].index(name)].region_names
                mn = rn[code] if rn is not None else "gap"
                ci = 1 if mn.endswith("+") else 2 if mn.endswith("-") else 3
            else:
                ci = code
            ax_m.broken_barh([(t0, max(t1 - t0, 0.0))], (y - 0.35, 0.7), color=_MODE_COLORS[ci])
        ev_t = [e.t for e in res.events if e.element == name]
        if ev_t:
            ax_m.plot(ev_t, [y + 0.42] * len(ev_t), "|", color="k", ms=4, mew=0.6)
    ax_m.set_yticks(range(len(moded)), [m[0] for m in reversed(moded)], fontsize=8)
    ax_m.set_ylim(-0.6, len(moded) - 0.4)
    ax_m.set_xlabel("time [s]")
    from matplotlib.patches import Patch

    fig.legend(
        handles=[
            Patch(color=c, label=lab) for c, lab in zip(_MODE_COLORS, _MODE_LABELS, strict=True)
        ],
        loc="outside lower center",
        ncol=4,
        fontsize=8,
        frameon=False,
        title="modes (tick: event of that element)",
        title_fontsize=8,
    )
    for ax in (ax_w, ax_T, ax_u):
        ax.grid(True, alpha=0.3)
    ax_m.grid(True, axis="x", alpha=0.3)
    ax_m.set_xlim(float(t[0]), t_hi)
    _mark_lockup([ax_w, ax_T, ax_u, ax_m], t_lock)
    if control_start is not None:
        for ax in (ax_w, ax_T, ax_u, ax_m):
            ax.axvline(control_start, color="0.3", ls="-.", lw=0.8)
        ax_w.annotate(
            "controller start", (control_start, 1.0), xycoords=("data", "axes fraction"),
            xytext=(3, -10), textcoords="offset points", fontsize=7, color="0.3",
        )  # fmt: skip
    _save(fig, path)
    return fig


def _power_label(model: Model, j: int) -> str:
    """Readable name of dissipation term ``j`` of ``model.power_names()``."""
    name = model.power_names()[j]
    if name.endswith(".ground"):
        return f"dissipated: {name.removesuffix('.ground')} viscous/drag to ground"
    if name.endswith(".damper"):
        return f"dissipated: {name.removesuffix('.damper')} damping"
    return f"dissipated: {name} friction"


def plot_energy(res: SimulationResult, path: str | Path | None = None) -> Figure:
    """Energy balance of run ``res`` [J]; saved as PNG to ``path`` if given. Returns the figure.

    Top: change of stored energy ``E(t) - E(0)``, work supplied ``W_in`` and energy dissipated by
    each element (elements that dissipate less than 0.1 % of the largest are left out). Bottom:
    residual ``E(t) - E(0) - W_in + sum(E_diss)`` (zero for an exact balance).
    """
    fig = _new_figure(2, [3.0, 1.3], (10.0, 6.5))
    ax, ax_r = fig.axes
    t = res.t
    model = res.model
    if res.work_in is None or res.dissipated is None:
        ax.text(0.5, 0.5, "energies were not integrated", ha="center", transform=ax.transAxes)
        _save(fig, path)
        return fig
    E = res.stored_energy()
    dE = E - E[0]
    D = res.dissipated
    ax.plot(t, res.work_in, color="k", lw=1.6, label="work in")
    ax.plot(t, dE, color="C0", lw=1.6, label="stored - stored(0)")
    final = D[-1]
    big = float(np.max(np.abs(final))) if final.size else 0.0
    order = np.argsort(-np.abs(final), kind="stable")
    shown = [int(j) for j in order if big > 0 and abs(final[j]) >= 1e-3 * big]
    for n, j in enumerate(shown):
        ax.plot(t, D[:, j], lw=1.1, ls="--", color=f"C{(n + 1) % 10}", label=_power_label(model, j))
    ax.set_ylabel("energy [J]")
    ax.legend(loc="best", fontsize=8, ncol=2)
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{model.chain.name}: energy balance")
    resid = dE - res.work_in + np.sum(D, axis=1)
    ax_r.plot(t, resid, color="C3", lw=1.0)
    ax_r.set_ylabel("residual [J]")
    ax_r.set_xlabel("time [s]")
    ax_r.grid(True, alpha=0.3)
    ax_r.set_title(
        f"residual (relative at the end: {res.energy_residual_rel:.2e})", fontsize=9, loc="left"
    )
    _save(fig, path)
    return fig


def plot_engagement(
    runs: list[tuple[str, SimulationResult]],
    *,
    reference: Any = None,
    lockups: list[float | None] | None = None,
    path: str | Path | None = None,
    title: str | None = None,
) -> Figure:
    """A clutch start in the layout of the paper's Fig. 14, one column per run.

    Rows: engine speed omega_1, primary-shaft speed omega_3 and the reference omega_r [rpm];
    controller command x_r and actuator position x_c [mm]; clutch torque tau_13 and engine torque
    C_1 [N m]; vehicle speed [km/h]. ``runs`` are ``(label, result)`` pairs of closed-loop runs;
    ``reference`` is omega_r(t) [rad/s] (a :class:`~drivetrain_ctrl.core.signals.Signal`);
    ``lockups`` the lock-up time [s] of each run (a dashed line). Saved to ``path`` if given.
    """
    from matplotlib.figure import Figure

    if not isinstance(runs, (list, tuple)) or not all(
        isinstance(r, tuple) and len(r) == 2 and isinstance(r[0], str) and hasattr(r[1], "model")
        for r in runs
    ):
        raise ValueError(
            f"plot_engagement: runs = {runs!r:.80}: give a list of (label, SimulationResult) pairs"
        )
    ncol = len(runs)
    if ncol == 0:
        raise ValueError("plot_engagement: runs is empty; give (label, SimulationResult) pairs")
    if lockups is not None and len(lockups) != ncol:
        raise ValueError(
            f"plot_engagement: lockups has {len(lockups)} entries for {ncol} runs (one per run)"
        )
    if lockups is not None:
        for k, tl in enumerate(lockups):
            if tl is not None and not is_finite_real(tl):
                raise ValueError(
                    f"plot_engagement: lockups[{k}] = {tl!r}: a lock-up time [s] or None"
                )
    if reference is not None and not callable(reference):
        raise ValueError(
            f"plot_engagement: reference = {reference!r}: a Signal (omega_r(t) [rad/s]) or None"
        )
    fig = Figure(figsize=(5.2 * ncol, 9.0), layout="constrained")
    axs = fig.subplots(4, ncol, sharex=True, squeeze=False)
    for j, (label, res) in enumerate(runs):
        m = res.model
        t = res.t
        ax = axs[:, j]
        ax[0].plot(t, res.state("omega_engine") / RPM_TO_RAD_S, label=r"$\omega_1$ engine")
        ax[0].plot(t, res.state("omega_primary") / RPM_TO_RAD_S, label=r"$\omega_3$ primary")
        if reference is not None:
            ax[0].plot(t, np.asarray(reference(t)) / RPM_TO_RAD_S, "k--", label=r"$\omega_r$")
        ax[0].set_ylabel("speed [rpm]")
        ax[0].set_title(label)
        cmd = res.extras.get("controller_command")
        if cmd is not None:
            ax[1].plot(t, 1e3 * np.asarray(cmd), label=r"$x_r$ command")
        ax[1].plot(t, 1e3 * res.u[:, m.input_names.index("pedal")], label=r"$x_c$ actuator")
        ax[1].set_ylabel("position [mm]")
        T = res.coupling_torques()
        c_clutch = [c.name for c in m.chain.couplings].index("clutch")
        ax[2].plot(t, T[:, c_clutch], label=r"$\tau_{13}$ clutch")
        src = res.source_torques()
        if src:
            ax[2].plot(t, next(iter(src.values())), label=r"$C_1$ engine")
        ax[2].set_ylabel("torque [N m]")
        ax[3].plot(t, 3.6 * res.state("v_vehicle"), label="vehicle")
        ax[3].set_ylabel("speed [km/h]")
        ax[3].set_xlabel("t [s]")
        if lockups is not None:
            _mark_lockup(list(ax), lockups[j])
        for a in ax:
            a.grid(True, alpha=0.3)
            if j == 0:
                a.legend(loc="best", fontsize=8)
    if title:
        fig.suptitle(title)
    _save(fig, path)
    return fig


# -- loop analysis and reports ------------------------------------------------------------------


def _pole_axes(ax: Axes, poles: Any, title: str) -> None:
    p = np.asarray(poles, dtype=float).reshape(-1, 2)
    ax.plot(p[:, 0], p[:, 1], "x")
    ax.axvline(0.0, color="k", lw=0.5)
    ax.set_xlabel("Re [1/s]")
    ax.set_ylabel("Im [rad/s]")
    ax.set_title(title, fontsize=9)


def _root_locus_axes(
    fig: Figure, ax: Axes, points: list[tuple[float, Any, str]], parameter: str, unit: str
) -> None:
    """Poles of each ``(value, [(re, im), ...], mode label)`` point, coloured by the value, one
    marker per distinct mode label (legend when there are several)."""
    vals = [v for v, _, _ in points]
    labels: list[str] = []
    for _, _, lb in points:
        if lb not in labels:
            labels.append(lb)
    markers = "os^Dv<>p*h"
    sc = None
    seen: set[str] = set()
    for v, poles, lb in points:
        p = np.asarray(poles, dtype=float).reshape(-1, 2)
        sc = ax.scatter(
            p[:, 0],
            p[:, 1],
            c=[v] * p.shape[0],
            vmin=min(vals),
            vmax=max(vals),
            s=9,
            marker=markers[labels.index(lb) % len(markers)],
            label=None if lb in seen else f"mode {labels.index(lb) + 1}",
        )
        seen.add(lb)
    ax.axvline(0.0, color="k", lw=0.5)
    ax.set_xlabel("Re [1/s]")
    ax.set_ylabel("Im [rad/s]")
    if len(labels) > 1:
        ax.legend(loc="best", fontsize=7)
    ax.set_title(f"root locus over {parameter} [{unit}]")
    if sc is not None:
        fig.colorbar(sc, ax=ax, label=f"{parameter} [{unit}]")


def plot_root_locus(
    points: list[tuple[float, Any, str]],
    *,
    parameter: str,
    unit: str,
    path: str | Path | None = None,
) -> Figure:
    """Root locus on a parameter grid: ``points`` are ``(value, poles, mode label)`` with poles as
    ``(re, im)`` pairs [1/s]; coloured by the value of ``parameter`` [``unit``], one marker per
    mode of the operating point. Saved to ``path`` as PNG if given."""
    from matplotlib.figure import Figure

    if not points:
        raise ValueError("plot_root_locus: points is empty; give (value, poles, mode label) tuples")
    fig = Figure(figsize=(6, 5), layout="constrained")
    _root_locus_axes(fig, fig.subplots(), points, parameter, unit)
    _save(fig, path)
    return fig


def plot_loop(
    omega: Any,
    bode: dict[str, tuple[Any, Any]],
    *,
    title: str,
    poles: Any = None,
    path: str | Path | None = None,
) -> Figure:
    """Bode diagram of loop transfer functions, e.g. ``L``, ``S``, ``T`` of a clutch loop.

    ``omega`` [rad/s]; ``bode`` maps a label to ``(magnitude [dB], phase [deg])`` on ``omega``
    (None or NaN for no value); ``poles``: optional ``(re, im)`` pairs [1/s] drawn in a panel on the
    right (the closed-loop poles). Saved to ``path`` as PNG if given.
    """
    from matplotlib.figure import Figure

    nw = len(omega)
    for k, (db, ph) in bode.items():
        if len(db) != nw or len(ph) != nw:
            raise ValueError(
                f"plot_loop: bode[{k!r}] has {len(db)} magnitudes and {len(ph)} phases for "
                f"{nw} frequencies in omega (one each per frequency)"
            )
    fig = Figure(figsize=(12 if poles is not None else 8, 6), layout="constrained")
    gs = fig.add_gridspec(
        2, 2 if poles is not None else 1, width_ratios=[2, 1][: 2 if poles is not None else 1]
    )
    am = fig.add_subplot(gs[0, 0])
    ap = fig.add_subplot(gs[1, 0], sharex=am)
    for k, (db, ph) in bode.items():
        am.semilogx(omega, [np.nan if v is None else v for v in db], label=k)
        ap.semilogx(omega, [np.nan if v is None else v for v in ph], label=k)
    am.axhline(0.0, color="k", lw=0.5)
    am.set_ylabel("magnitude [dB]")
    ap.set_ylabel("phase [deg]")
    ap.set_xlabel("omega [rad/s]")
    if bode:
        am.legend()
    am.set_title(title)
    if poles is not None:
        _pole_axes(fig.add_subplot(gs[:, 1]), poles, "closed-loop poles")
    _save(fig, path)
    return fig


def _compress(z: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """The radius mapping of the Nyquist overview: ``|L|`` kept up to 1, ``1 + log10 |L|`` beyond
    (a monotone map of the radius: encirclements of -1, which stays at -1, are unchanged)."""
    r = np.abs(z)
    with np.errstate(divide="ignore"):
        rho = np.where(r <= 1.0, r, 1.0 + np.log10(np.maximum(r, 1.0)))
    return np.asarray(rho * np.exp(1j * np.angle(z)), dtype=complex)


def plot_nyquist(
    real: Any,
    imag: Any,
    *,
    encirclements: int,
    open_loop_unstable_poles: int,
    closed_loop_unstable_poles: int,
    omega: Any = None,
    boundary_poles: int = 0,
    dt: float | None = None,
    title: str | None = None,
    path: str | Path | None = None,
) -> Figure:
    """Nyquist curve ``L`` for ``omega >= 0`` (its mirror image dashed) with the critical point
    -1, in two panels: left the whole curve, low frequencies included, with the radius compressed
    beyond the unit circle (``1 + log10 |L|``; circles mark ``|L|`` = 1, 10, 100, ...; dots mark
    decades of ``omega`` [rad/s], given as ``omega``), right a linear window around -1 with the
    unit circle. The title gives the encirclements N of -1, the open-loop unstable poles P and
    the closed-loop unstable poles Z = N + P, and how ``boundary_poles`` (integrators) are counted
    (:func:`drivetrain_ctrl.linear.margins.nyquist_data`); ``dt`` [s] marks a sampled loop;
    ``title`` is put in front. Saved to ``path`` as PNG if given."""
    from matplotlib.figure import Figure

    z = np.asarray(real, dtype=float) + 1j * np.asarray(imag, dtype=float)
    if omega is not None and len(omega) != z.size:
        raise ValueError(
            f"plot_nyquist: omega has {len(omega)} values for {z.size} points (one per point)"
        )
    fig = Figure(figsize=(11.5, 5.6), layout="constrained")
    ax_c, ax_z = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.15, 1.0]})
    th = np.linspace(0, 2 * np.pi, 361)
    # left: the whole curve, radius compressed
    zc = _compress(z)
    rmax = float(np.max(np.abs(zc))) if zc.size else 1.0
    for k in range(int(math.floor(max(rmax, 1.0))) + 1):
        if k == 0:
            continue
        ax_c.plot(k * np.cos(th), k * np.sin(th), color="0.8", lw=0.6, zorder=0)
        ax_c.annotate(
            f"|L| = {10 ** (k - 1):g}",
            (k * np.cos(np.pi / 4), k * np.sin(np.pi / 4)),
            fontsize=7,
            color="0.45",
        )
    ax_c.plot(zc.real, zc.imag, "C0", lw=1.4, label="L, omega > 0")
    ax_c.plot(zc.real, -zc.imag, "C0--", lw=0.8, label="omega < 0 (mirror)")
    if omega is not None and z.size > 1:
        w = np.asarray(omega, dtype=float)
        pos = w > 0
        if np.count_nonzero(pos) > 1:
            lw = np.log10(w[pos])
            decades = np.arange(math.ceil(lw.min()), math.floor(lw.max()) + 1)
            placed: list[complex] = []
            for d in decades:
                zi = np.interp(d, lw, zc[pos].real) + 1j * np.interp(d, lw, zc[pos].imag)
                # one label per place: the decades where L has fallen to ~0 crowd the origin
                if any(abs(zi - q) < 0.06 * max(rmax, 1.6) for q in placed):
                    continue
                placed.append(zi)
                ax_c.plot([zi.real], [zi.imag], "o", color="C1", ms=3.5, zorder=3)
                ax_c.annotate(
                    f"{10.0**d:g}", (zi.real, zi.imag), xytext=(3, 3),
                    textcoords="offset points", fontsize=7, color="C1",
                )  # fmt: skip
            ax_c.plot([], [], "o", color="C1", ms=3.5, label="omega [rad/s]")
    ax_c.plot([-1], [0], "r+", ms=12, mew=2, label="-1")
    lim = max(1.6, 1.08 * rmax)
    ax_c.set_xlim(-lim, lim)
    ax_c.set_ylim(-lim, lim)
    ax_c.set_aspect("equal")
    ax_c.set_xlabel("Re L (radius compressed beyond |L| = 1)")
    ax_c.set_ylabel("Im L")
    ax_c.set_title("whole curve, low frequencies included", fontsize=9)
    ax_c.legend(loc="lower left", fontsize=7)
    # right: linear window around -1
    ax_z.plot(np.cos(th), np.sin(th), color="0.7", lw=0.6)
    ax_z.plot(z.real, z.imag, "C0", lw=1.4)
    ax_z.plot(z.real, -z.imag, "C0--", lw=0.8)
    ax_z.plot([-1], [0], "r+", ms=12, mew=2)
    ax_z.axhline(0.0, color="0.5", lw=0.5)
    ax_z.axvline(0.0, color="0.5", lw=0.5)
    ax_z.set_xlim(-3.0, 1.5)
    ax_z.set_ylim(-2.25, 2.25)
    ax_z.set_aspect("equal")
    ax_z.set_xlabel("Re L")
    ax_z.set_ylabel("Im L")
    ax_z.set_title("around -1 (linear scale; grey: unit circle)", fontsize=9)
    conv = (
        f"; {boundary_poles} open-loop pole(s) on the stability boundary (integrator) counted "
        "stable: the contour passes them on the unstable side"
        if boundary_poles
        else ""
    )
    head = (title + ": ") if title else ""
    kind = f"sampled, dt = {dt:g} s" if dt else "continuous"
    fig.suptitle(
        f"{head}Nyquist ({kind}): N = {encirclements} clockwise encirclements of -1, "
        f"P = {open_loop_unstable_poles}, Z = N + P = {closed_loop_unstable_poles} unstable "
        f"closed-loop poles" + ("\n" + conv[2:] if conv else ""),
        fontsize=10,
    )
    _save(fig, path)
    return fig


def report_figures(data: dict[str, Any]) -> dict[str, Figure]:
    """The figures of a controller report (:func:`drivetrain_ctrl.reporting.controller_report.build_report`), drawn
    from its ``data`` only: ``{name: Figure}`` for bode, root_locus, nyquist, step, engagement,
    lock."""
    from matplotlib.figure import Figure

    cname = data["inputs"]["controller_name"]
    slip = data["modes"]["slip"][cname]
    lock = data["modes"]["lock"][cname]
    figs: dict[str, Figure] = {}

    b = slip["bode"]
    figs["bode"] = plot_loop(
        b["L"]["omega"],
        {k: (b[k]["magnitude_db"], b[k]["phase_deg"]) for k in ("L", "S", "T")},
        title=f"Bode of L, S, T (slip, controller {cname})",
    )

    # root loci
    fig = Figure(figsize=(11, 4.5), layout="constrained")
    for ax, key in zip(fig.subplots(1, 2), ("gain", "mu_slope"), strict=True):
        rl = slip["root_locus"][key]
        pts = [
            (
                pt["value"],
                pt["poles"],
                ", ".join(f"{e}={m}" for e, m in pt.get("modes", {}).items()),
            )
            for pt in rl["points"]
        ]
        _root_locus_axes(fig, ax, pts, rl["parameter"], rl["unit"])
        if key == "mu_slope":
            jn = (slip.get("judder") or {}).get("numeric") or {}
            crit = jn.get("mu_slope_crit")
            ax.set_title(
                f"root locus over mu_slope [s/rad]\njudder threshold {crit:.4g} s/rad "
                f"({jn['frequency_hz']:.3g} Hz mode)"
                if crit is not None
                else "root locus over mu_slope [s/rad]\njudder threshold not available",
                fontsize=10,
            )
    dts = slip.get("sample_period_s")
    fig.suptitle(
        f"Slip-mode poles (controller {cname}, {data['inputs']['model']} model); colour: the "
        "parameter's value"
        + (
            f"\nsampled loop: poles z drawn as ln(z)/dt, frequencies folded below {0.5 / dts:g} Hz"
            if dts
            else ""
        )
    )
    figs["root_locus"] = fig

    ny = slip["nyquist"]
    figs["nyquist"] = plot_nyquist(
        ny["real"],
        ny["imag"],
        omega=ny.get("omega"),
        encirclements=ny["encirclements"],
        open_loop_unstable_poles=ny["open_loop_unstable_poles"],
        closed_loop_unstable_poles=ny["closed_loop_unstable_poles"],
        boundary_poles=ny.get("boundary_poles", 0),
        dt=ny.get("dt"),
        title=f"L of controller {cname} (slip)",
    )

    # step comparison
    steps = data["linear_vs_nonlinear"]["steps"]
    fig = Figure(figsize=(11, 4), layout="constrained")
    axes = fig.subplots(1, len(steps), squeeze=False)
    for ax, (name, s) in zip(axes[0], sorted(steps.items()), strict=True):
        ax.plot(s["t_s"], s["linear_rpm"], label="linear (forced_response)")
        ax.plot(s["t_s"], s["nonlinear_rpm"], "--", label="switching plant")
        ax.set_xlabel(f"time after the step at {s['t_start_s']:.3g} s [s]")
        ax.set_ylabel("delta omega_engine [rpm]")
        ax.set_title(f"{name} reference step {s['step_rpm']:+g} rpm")
        ax.legend(fontsize=8)
    figs["step"] = fig

    # engagement
    es = data["engagement_series"]
    fig = Figure(figsize=(8, 8), layout="constrained")
    a0, a1, a2 = fig.subplots(3, 1, sharex=True)
    a0.plot(es["t_s"], es["omega_engine_rpm"], label="engine omega_1")
    a0.plot(es["t_s"], es["omega_driven_rpm"], label=es["driven_state"])
    if es["omega_ref_rpm"] is not None:
        t0 = es.get("control_start_s") or 0.0
        tr = [(t, r) for t, r in zip(es["t_s"], es["omega_ref_rpm"], strict=True) if t >= t0]
        a0.plot([t for t, _ in tr], [r for _, r in tr], "k--", lw=1.0, label="reference omega_r")
    a0.set_ylabel("speed [rpm]")
    a0.legend(fontsize=8)
    if es.get("x_r_m") is not None:
        a1.plot(es["t_s"], [1e3 * v for v in es["x_r_m"]], "k--", lw=1.0, label="command x_r")
    a1.plot(es["t_s"], [1e3 * v for v in es["x_c_m"]], label="actuator x_c (pedal)")
    a1.set_ylabel("clutch position [mm]")
    a1.legend(fontsize=8)
    a2.plot(es["t_s"], es["v_vehicle_kmh"])
    a2.set_ylabel("vehicle [km/h]")
    a2.set_xlabel("t [s]")
    fig.suptitle(
        f"Engagement: scenario {data['inputs']['scenario']}, controller {cname}, "
        f"{data['inputs']['model']} model"
    )
    t_op = data["operating_points"]["slip"]["t_s"]
    for ax in (a0, a1, a2):
        ax.axvline(t_op, color="r", lw=0.6)
        if es.get("control_start_s") is not None:
            ax.axvline(es["control_start_s"], color="0.3", ls="-.", lw=0.8)
        ax.grid(True, alpha=0.3)
    a0.annotate(
        "slip operating point", (t_op, 1.0), xycoords=("data", "axes fraction"),
        xytext=(3, -10), textcoords="offset points", fontsize=7, color="r",
    )  # fmt: skip
    figs["engagement"] = fig

    # lock: open-loop poles of the locked driveline
    import textwrap

    fig = Figure(figsize=(7, 5), layout="constrained")
    sm = lock.get("shuffle_modes") or []
    ttl = ", ".join(f"{m['natural_frequency_hz']:.3g} Hz (zeta {m['damping']:.3g})" for m in sm)
    if lock.get("open_loop_poles") is None:
        ttl = f"not available: {lock.get('reasons', {}).get('shuffle_modes', 'no locked point')}"
    _pole_axes(
        fig.subplots(),
        lock.get("open_loop_poles") or [],
        "\n".join(textwrap.wrap(f"shuffle modes: {ttl or 'none'}", 80)),
    )
    fig.suptitle(
        f"Locked driveline, open-loop poles (controller {cname}, {data['inputs']['model']} model)",
        fontsize=10,
    )
    figs["lock"] = fig
    return figs


#: the PDF report's page (A4 portrait) and margins [in]
PDF_PAGE: tuple[float, float] = (8.27, 11.69)
PDF_MARGINS: tuple[float, float, float, float] = (0.6, 0.6, 0.7, 0.7)  # left, right, top, bottom

#: resolution [dpi] at which figures are placed into the PDF's pages
PDF_FIGURE_DPI: int = 150

# font sizes [pt] of the PDF's text styles; tables are monospaced
_PDF_SIZES = {"h1": 13.0, "h2": 11.0, "p": 8.0, "caption": 8.0, "t": 6.5}

#: the block kinds of :func:`pdf_pages`
PDF_BLOCKS: tuple[str, ...] = ("h1", "h2", "p", "table", "figure")


def _text_width(s: str, size: float, mono: bool, renderer: Any) -> float:
    """Width of ``s`` [in] at ``size`` pt as the PDF draws it."""
    from matplotlib.font_manager import FontProperties

    fp = FontProperties(family="monospace" if mono else "sans-serif", size=size)
    w, _, _ = renderer.get_text_width_height_descent(s, fp, ismath=False)
    return float(w) / renderer.dpi


def _wrap_to(text: str, width_in: float, size: float, mono: bool, renderer: Any) -> list[str]:
    """``text`` wrapped into lines no wider than ``width_in`` [in] (measured; a word longer than a
    line is broken)."""
    import textwrap

    if not text:
        return [""]
    n = max(8, int(width_in * 72 / (0.45 * size)))  # a first guess of the characters per line
    while True:
        lines = textwrap.wrap(text, n, break_long_words=True, break_on_hyphens=False) or [""]
        if n <= 8 or all(_text_width(x, size, mono, renderer) <= width_in for x in lines):
            return lines
        n -= max(1, n // 40)


def _table_lines(rows: list[list[str]], width_chars: int) -> list[list[str]]:
    """The rows of a table as monospaced lines that fit ``width_chars``: every column as wide as its
    widest cell, and when that is too wide for the page the widest columns shrink (to no less
    than 8 characters, or their header) and their cells wrap. Returns one list of lines per row."""
    import textwrap

    ncol = max(len(r) for r in rows)
    rows = [list(r) + [""] * (ncol - len(r)) for r in rows]
    gap = 2
    natural = [max(max(len(r[i]) for r in rows), 1) for i in range(ncol)]
    avail = max(width_chars - gap * (ncol - 1), 8 * ncol)
    width = list(natural)
    while sum(width) > avail:
        i = max(range(ncol), key=lambda k: width[k])
        floor = max(8, min(len(rows[0][i].split(" ")[0]), 20))
        if width[i] <= floor:
            break
        width[i] = max(floor, width[i] - max(1, (sum(width) - avail) // max(1, ncol)))
    out = []
    for r in rows:
        cells = [
            textwrap.wrap(c, width[i], break_long_words=True, break_on_hyphens=False) or [""]
            for i, c in enumerate(r)
        ]
        h = max(len(c) for c in cells)
        out.append(
            [
                (" " * gap)
                .join(
                    (cells[i][k] if k < len(cells[i]) else "").ljust(width[i]) for i in range(ncol)
                )
                .rstrip()
                for k in range(h)
            ]
        )
    return out


def pdf_pages(blocks: list[tuple[Any, ...]], *, header: str | None = None) -> list[Figure]:
    """The pages (A4 :class:`~matplotlib.figure.Figure` s) of a report laid out from ``blocks``, in
    order: ``("h1" | "h2" | "p", text)`` headings and paragraphs (wrapped to the page),
    ``("table", caption, rows)`` with ``rows[0]`` the header (columns sized to the page, long
    cells wrapped, the header repeated on a continuation page) and ``("figure", Figure)`` placed
    where it stands, scaled to the text width (shrunk to fit the rest of a page, or moved to the
    next one). ``header`` is printed at the foot of every page with the page number."""
    from io import BytesIO

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.image import imread
    from matplotlib.lines import Line2D

    for i, b in enumerate(blocks):
        ok = isinstance(b, tuple | list) and len(b) >= 2 and b[0] in PDF_BLOCKS
        if ok and b[0] in ("h1", "h2", "p"):
            ok = len(b) == 2 and isinstance(b[1], str)
        elif ok and b[0] == "table":
            ok = len(b) == 3 and isinstance(b[2], list) and len(b[2]) >= 1
        elif ok:
            ok = len(b) == 2 and isinstance(b[1], Figure)
        if not ok:
            raise ValueError(
                f"pdf_pages: blocks[{i}] = {b!r:.80}: must be (h1|h2|p, text), "
                "(table, caption, rows) or (figure, Figure)"
            )
    W, H = PDF_PAGE
    ml, mr, mt, mb = PDF_MARGINS
    tw = W - ml - mr
    measure = FigureCanvasAgg(Figure(figsize=(1, 1), dpi=72)).get_renderer()
    pages: list[Figure] = []
    page: Figure | None = None
    y = 0.0  # distance from the top [in]

    def new_page() -> Figure:
        nonlocal page, y
        page = Figure(figsize=PDF_PAGE)
        pages.append(page)
        y = mt
        return page

    def room(h: float) -> Figure:
        """The current page if ``h`` [in] fits below the cursor, else a new one."""
        if page is None or y + h > H - mb + 1e-9:
            return new_page()
        return page

    def line(s: str, style: str, *, x: float = ml) -> None:
        nonlocal y
        size = _PDF_SIZES[style]
        lh = size * 1.38 / 72
        pg = room(lh)
        kw: dict[str, Any] = {"fontsize": size, "va": "top", "parse_math": False}
        if style == "t":
            kw["family"] = "monospace"
        else:
            kw["family"] = "sans-serif"
            kw["weight"] = "bold" if style in ("h1", "h2") else "normal"
            kw["style"] = "italic" if style == "caption" else "normal"
        pg.text(x / W, 1 - y / H, s, **kw)
        y += lh

    for b in blocks:
        kind = b[0]
        if kind in ("h1", "h2", "p"):
            size = _PDF_SIZES[kind]
            lines = _wrap_to(b[1], tw, size, False, measure)
            if kind in ("h1", "h2"):
                room(0.15 + size * 1.38 / 72 * (len(lines) + 4))  # keep with what follows
                y += 0.12 if y > mt else 0.0
            for s in lines:
                line(s, kind)
            y += 0.05
        elif kind == "table":
            caption, rows = b[1], [[str(c) for c in r] for r in b[2]]
            ch = _text_width("0" * 40, _PDF_SIZES["t"], True, measure) / 40
            tlines = _table_lines(rows, int(tw / ch))
            lh = _PDF_SIZES["t"] * 1.38 / 72
            room(lh * (len(tlines[0]) + (len(tlines[1]) if len(tlines) > 1 else 0) + 2))
            for s in _wrap_to(caption, tw, _PDF_SIZES["caption"], False, measure):
                line(s, "caption")

            def head(cont: bool, tlines: list[list[str]] = tlines) -> None:
                nonlocal y
                if cont:
                    line("(continued)", "caption")
                for s in tlines[0]:
                    line(s, "t")
                assert page is not None
                page.add_artist(Line2D([ml / W, 1 - mr / W], [1 - y / H] * 2, lw=0.6, color="k"))
                y += 0.03

            head(False)
            ruled = any(len(r) > 1 for r in tlines[1:])  # wrapped cells: a rule between rows
            for k, r in enumerate(tlines[1:]):
                if page is None or y + lh * len(r) > H - mb:
                    new_page()
                    head(True)
                for s in r:
                    line(s, "t")
                if ruled and k < len(tlines) - 2:
                    assert page is not None
                    page.add_artist(
                        Line2D([ml / W, 1 - mr / W], [1 - (y + 0.01) / H] * 2, lw=0.3, color="0.7")
                    )
                    y += 0.02
            y += 0.1
        else:
            f = b[1]
            fw, fh = (float(v) for v in f.get_size_inches())
            w = min(tw, fw)
            h = fh * w / fw
            full = H - mt - mb
            if h > full:
                h, w = full, fw * full / fh
            left = H - mb - y
            if page is None or h > left:
                if page is not None and left >= 0.6 * h:
                    h, w = left, fw * left / fh
                else:
                    new_page()
            buf = BytesIO()
            f.savefig(buf, format="png", dpi=PDF_FIGURE_DPI)
            buf.seek(0)
            img = imread(buf, format="png")
            assert page is not None
            ax = page.add_axes((ml / W + (tw - w) / 2 / W, 1 - (y + h) / H, w / W, h / H))
            ax.imshow(img, interpolation="antialiased", aspect="auto")
            ax.set_axis_off()
            y += h + 0.15
    if not pages:
        new_page()
    n = len(pages)
    for k, pg in enumerate(pages):
        foot = f"{header} - page {k + 1} of {n}" if header else f"page {k + 1} of {n}"
        pg.text(0.5, mb / 2 / H, foot, ha="center", va="center", fontsize=7, color="0.4",
                parse_math=False)  # fmt: skip
    return pages


def write_report_pdf(
    blocks: list[tuple[Any, ...]], path: str | Path, *, header: str | None = None
) -> None:
    """Write the pages of :func:`pdf_pages` (``blocks``, ``header``) as a PDF to ``path``; no
    creation date (the same input gives the same file)."""
    from matplotlib.backends.backend_pdf import PdfPages

    pages = pdf_pages(blocks, header=header)
    with PdfPages(path, metadata={"Creator": "drivetrain_ctrl", "CreationDate": None}) as pdf:
        for pg in pages:
            pdf.savefig(pg)
