"""Command line interface ``drivetrain-ctrl``.

Subcommands::

    drivetrain-ctrl simulate --scenario NAME|FILE.toml --model full|reduced
                             --params NAME|FILE.toml --out DIR [--rtol R] [--t-end T]
    drivetrain-ctrl demo --out DIR [--quick] [--params NAME|FILE.toml]
    drivetrain-ctrl params show [NAME|FILE.toml] [--provenance]
    drivetrain-ctrl params list
    drivetrain-ctrl scenarios list
    drivetrain-ctrl study run STUDY.toml --out DIR [--workers N] [--scheduler ADDRESS]
    drivetrain-ctrl study report DIR [--out OUT] [--worst N] [--no-resimulate]
    drivetrain-ctrl design pi|robust-pi|pid|hinf --spec NAME|SPEC.toml --out CONTROLLER.toml
                           [--name NAME] [--no-check]
    drivetrain-ctrl compare [--controllers paper,pi,robust-pi,hinf[,FILE.toml...]]
                            [--scenarios all|NAME,...] [--model full|reduced]
                            [--params NAME|FILE] [--weights KEY=W,...] [--workers N] --out DIR

``simulate`` writes into DIR: ``trajectory.csv`` and ``events.csv`` (column names carry units),
``metrics.json`` (figures of merit, :func:`drivetrain_ctrl.sim.metrics.engagement_metrics`;
deterministic: the same inputs give the same bytes), ``timing.json`` (``wall_time_s``: the
simulation's own wall time [s], measured after a 1-ms run of the same model has loaded the
compiled kernels, whose time is ``kernel_load_s``; ``total_wall_time_s`` including the outputs;
steps, function evaluations), ``overview.png`` and ``energy.png``. ``demo`` runs both built-in scenarios on the
full and the reduced model (``--quick``: reduced only) into ``DIR/<scenario>-<model>/`` and
writes ``DIR/summary.md``. ``design`` designs a clutch controller from a design spec
(:mod:`drivetrain_ctrl.design.from_spec`): it prints the achieved figures per plant and the
limiting plants, writes the controller file, then runs it on the switching plant (the spec's
``[check]``: ``paper-start`` on both models by default) and prints its engagement metrics beside
the linear figures; an engine stall, no lock-up or a Zeno stop is said loudly (exit code 1, the
file is written all the same).

``compare`` runs every controller on every scenario in parallel and writes ``DIR/compare.html``,
``DIR/compare.pdf`` and ``DIR/data.json`` (:mod:`drivetrain_ctrl.studies.compare`); a controller
or scenario that cannot take part is named on stderr and in the report, the others compare.

``study run`` runs a robustness study file (:mod:`drivetrain_ctrl.studies.study`) on Dask into
``DIR/results/*.parquet`` and resumes an interrupted run (:mod:`drivetrain_ctrl.studies.runner`).
``study report`` writes ``report.html``, ``report.pdf`` and ``data.json`` of a study folder
into it (or ``--out``; :mod:`drivetrain_ctrl.reporting.study_report`).

Exit codes: 0 success; 1 the simulation failed (e.g. Zeno) or an output could not be written;
2 invalid command line or input (unknown scenario or parameter set, invalid or misspelt key in a
TOML file), reported on stderr without a traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import textwrap
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .control.laws import ControllerError, builtin_controllers
from .core.serialize import json_ready
from .core.tables import PwlTable
from .core.validate import real_number
from .plant.params import (
    DEFAULT_SET,
    DrivetrainParams,
    available_parameter_sets,
    field_info,
    field_paths,
    load_params,
)
from .scenarios.scenario import LOOPS, Scenario, ScenarioError, builtin_scenarios, load_scenario
from .sim.metrics import METRICS, metric_table
from .sim.simulator import SimulationOptions, ZenoError
from .sim.warmup import ensure_compiled
from .studies.case import Case, CaseError, simulate_case

__all__ = ["main", "run_simulation"]

PROG = "drivetrain-ctrl"
MODELS = ("full", "reduced")
DEFAULT_PARAMS = DEFAULT_SET
#: the files ``run_simulation`` writes: four tables, then the two plots (with ``plots``)
SIMULATION_FILES: tuple[str, ...] = (
    "trajectory.csv",
    "events.csv",
    "metrics.json",
    "timing.json",
    "overview.png",
    "energy.png",
)


def _controller_names(sep: str) -> str:
    """The built-in controller names joined by ``sep`` (help and error texts)."""

    return sep.join(builtin_controllers())


class InputError(Exception):
    """Invalid user input (exit code 2)."""


class RunError(Exception):
    """A simulation failed or an output could not be written (exit code 1)."""


def _msg(exc: BaseException) -> str:
    if isinstance(exc, KeyError) and exc.args:
        return str(exc.args[0])
    return str(exc) or type(exc).__name__


# ------------------------------------------------------------------------------------------------
# loading
# ------------------------------------------------------------------------------------------------


def _load_params(source: str) -> DrivetrainParams:
    try:
        return load_params(source)
    except FileNotFoundError as exc:
        raise InputError(f"parameter file not found: {exc.filename or source}") from None
    except (ValueError, OSError) as exc:  # ParameterError is a ValueError
        raise InputError(f"parameters: {_msg(exc)}") from None


def _load_scenario(source: str, params: DrivetrainParams | None = None) -> Scenario:
    try:
        return load_scenario(source, params=params)
    except (ValueError, OSError) as exc:  # ScenarioError is a ValueError
        raise InputError(f"scenario: {_msg(exc)}") from None


# ------------------------------------------------------------------------------------------------
# one run
# ------------------------------------------------------------------------------------------------


def _write_json(path: Path, data: Any) -> None:
    path.write_text(json.dumps(data, sort_keys=True, indent=2) + "\n", encoding="utf-8")


def run_simulation(
    scenario: Scenario,
    params: DrivetrainParams,
    kind: str,
    out: Path | str,
    *,
    rtol: float | None = None,
    t_end: float | None = None,
    plots: bool = True,
    controller: str | None = None,
    loop: str | None = None,
) -> dict[str, Any]:
    """Simulate ``scenario`` on the ``kind`` model of ``params`` and write the outputs to ``out``.

    ``controller``: a built-in controller name or a controller TOML file (closed loop), None for
    an open-loop run. ``loop``: ``"closed"``, ``"open"`` or None (the scenario's own; a scenario
    with both a controller part and a pedal signal runs closed loop unless told otherwise).

    Returns ``{"metrics": ..., "timing": ..., "files": [...]}``. Raises :class:`InputError`
    for invalid options and :class:`RunError` if the simulation fails.
    """
    tic = time.perf_counter()
    if not isinstance(plots, bool):
        raise InputError(f"plots = {plots!r}: must be True or False")
    out = Path(out)
    _check_out_dir(out)
    try:
        SimulationOptions() if rtol is None else SimulationOptions(rtol=rtol)
    except ValueError as exc:
        raise InputError(f"--rtol: {exc}") from None
    try:
        scenario.for_loop(loop).check_horizon(t_end, arg="--t-end")
    except ScenarioError as exc:
        raise InputError(str(exc)) from None
    try:
        case = Case(
            scenario=scenario,
            params=params,
            model=kind,
            loop=loop,
            controller=controller,
            rtol=rtol,
            t_end=t_end,
        )
        ensure_compiled()  # the progress notice, if the kernels are not cached
        run = simulate_case(case, preload=True)
    except CaseError as exc:
        raise InputError(str(exc)) from None
    except (ZenoError, RuntimeError) as exc:
        raise RunError(f"{scenario.name} / {kind} model: simulation failed: {exc}") from None
    res, spec, opts = run.result, run.spec, run.options
    load_s = run.kernel_load_s
    metrics = run.metrics
    record: dict[str, Any] = {
        "scenario": scenario.name,
        "loop": run.scenario.loop,
        "parameter_set": params.name,
        "controller": spec.to_dict() if spec is not None else None,
        "rtol": opts.rtol,
        "atol": opts.atol,
        **metrics,
    }
    record = json_ready(record)
    try:
        out.mkdir(parents=True, exist_ok=True)
        files = list(SIMULATION_FILES[:4])
        res.to_dataframe().to_csv(out / "trajectory.csv", index=False, lineterminator="\n")
        res.events_dataframe().to_csv(out / "events.csv", index=False, lineterminator="\n")
        _write_json(out / "metrics.json", record)
        if plots:
            from .reporting.figures import plot_energy, plot_simulation  # matplotlib on demand

            closed = spec is not None
            plot_simulation(
                res,
                out / "overview.png",
                scenario=scenario.name,
                controller=spec.name if spec is not None else None,
                reference=scenario.reference if closed else None,
                control_start=scenario.start_time if closed else None,
            )
            plot_energy(res, out / "energy.png")
            files += SIMULATION_FILES[4:]
        timing = {
            "wall_time_s": float(res.stats["wall_time_s"]),
            "kernel_load_s": load_s,
            "total_wall_time_s": time.perf_counter() - tic,
            "steps": int(res.stats["steps"]),
            "rejected_steps": int(res.stats["rejected"]),
            "nfev": int(res.stats["nfev"]),
            "n_samples": int(res.t.shape[0]),
        }
        _write_json(out / "timing.json", timing)
    except OSError as exc:
        raise RunError(f"cannot write outputs to {out}: {exc}") from None
    return {"metrics": record, "timing": timing, "files": files}


def _check_out_dir(out: Path) -> None:
    """Raise :class:`InputError` before any work if ``out`` cannot be the output directory."""
    for p in (out, *out.parents):
        if p.exists():
            if not p.is_dir():
                what = f"--out {out}" if p == out else f"--out {out}: {p}"
                raise InputError(f"{what} is an existing file, not a directory")
            break


def _note_existing(out: Path) -> None:
    """Say on stderr that ``out`` already holds files (outputs of the same names are replaced)."""
    if out.is_dir() and any(out.iterdir()):
        print(
            f"{PROG}: writing into the existing {out}/: earlier outputs of the same names are "
            "replaced",
            file=sys.stderr,
        )


def _fmt(v: Any, spec: str = ".4g") -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        if spec == ".4g" and 1e3 <= abs(v) < 1e9:
            return f"{v:.0f}"
        return format(v, spec)
    return str(v)


#: the figures of merit the console quotes after a run, under their names in ``metrics.json``
CONSOLE_METRICS: tuple[str, ...] = (
    "lockup_time_s",
    "engagement_time_s",
    "clutch_energy_J",
    "engine_speed_min_rpm",
    "engine_speed_max_rpm",
    "lurch_rad_s2",
    "jerk_max_m_s3",
    "tracking_rms_rpm",
    "torque_match_rms_Nm",
    "final_vehicle_speed_kmh",
    "energy_residual_rel",
)


def _fmt_metric(key: str, v: Any) -> str:
    """A metric's value as the console and ``summary.md`` quote it."""
    return _fmt(v, ".2e" if key == "energy_residual_rel" else ".4g")


def _summary_line(m: dict[str, Any], timing: dict[str, Any]) -> str:
    """The console summary of one run: what ran, then ``name value`` of :data:`CONSOLE_METRICS`
    (the names of ``metrics.json``, whose suffix is the unit; ``-``: undefined, null)."""
    ctl = f", controller {m['controller']['name']}" if m.get("controller") else ""
    notes = "".join(f"\n  note: {n}" for n in m.get("notes") or [])
    figures = textwrap.fill(
        ", ".join(f"{k} {_fmt_metric(k, m[k])}" for k in CONSOLE_METRICS),
        width=100,
        initial_indent="  ",
        subsequent_indent="  ",
        break_long_words=False,
        break_on_hyphens=False,
    )
    return (
        f"{m['scenario']} / {m['model']} model ({m['parameter_set']}{ctl}): {m['status']}, "
        f"{m['n_samples']} samples, {m['n_events']} events, {timing['wall_time_s']:.3g} s\n"
        + figures
        + notes
    )


# ------------------------------------------------------------------------------------------------
# subcommands
# ------------------------------------------------------------------------------------------------


def _cmd_simulate(args: argparse.Namespace) -> int:
    params = _load_params(args.params)
    scenario = _load_scenario(args.scenario, params)
    out = Path(args.out)
    replaced = [f for f in SIMULATION_FILES if (out / f).is_file()]
    r = run_simulation(
        scenario,
        params,
        args.model,
        out,
        rtol=args.rtol,
        t_end=args.t_end,
        controller=args.controller,
        loop=args.loop,
    )
    print(_summary_line(r["metrics"], r["timing"]))
    print(f"  outputs: {out}/ ({', '.join(r['files'])})")
    if replaced:
        print(f"  replaced the earlier {', '.join(replaced)} in {out}/", file=sys.stderr)
    return 0


#: controllers the demo runs the closed-loop scenarios with
DEMO_CONTROLLERS: tuple[str, ...] = ("paper", "pi")
#: the built-in scenarios the demo runs (the harder starts of issue 21 are left to the comparison
#: and to analyses/hard_scenarios.py: they would triple the demo's time)
DEMO_SCENARIOS: tuple[str, ...] = ("engage-ramp", "tip-in", "paper-start")

#: the rows of the demo's summary table: the figures of merit (:data:`METRICS` of kind
#: ``"figure"``) and the run's status, size and energy check, under their names in ``metrics.json``
SUMMARY_METRICS: tuple[str, ...] = (
    ("status",)
    + tuple(k for k, info in METRICS.items() if info.kind == "figure")
    + ("n_events", "n_samples", "energy_residual_rel")
)


def _summary_md(
    runs: list[tuple[str, str, dict[str, Any]]], params: DrivetrainParams, quick: bool
) -> str:
    scen = builtin_scenarios(params)
    lines = [
        "# drivetrain-ctrl demo",
        "",
        f"Parameter set **{params.name}**: {params.description}.",
        "",
        "Runs: the built-in scenarios on the "
        + ("reduced model only (`--quick`)." if quick else "full and the reduced model."),
        "",
    ]
    for name, sc in scen.items():
        ctl = f" Controllers: {', '.join(DEMO_CONTROLLERS)}." if sc.needs_controller else ""
        lines.append(f"- `{name}` (gear {sc.gear}, {sc.t_end:g} s): {sc.description}{ctl}")
    lines += ["", "## Figures of merit", ""]
    heads = [f"{s} / {k}" for s, k, _ in runs]
    lines.append("| metric | " + " | ".join(heads) + " |")
    lines.append("|---|" + "---:|" * len(runs))
    for key in SUMMARY_METRICS:
        cells = [_fmt_metric(key, r["metrics"].get(key)) for _, _, r in runs]
        lines.append(f"| `{key}` | " + " | ".join(cells) + " |")
    cells = [_fmt(r["timing"]["wall_time_s"], ".3g") for _, _, r in runs]
    lines.append("| simulation wall time [s] | " + " | ".join(cells) + " |")
    lines += [
        "",
        "The names are those of `metrics.json`; `-`: undefined for the run (null). Definitions:",
        "",
    ]
    for key, unit, text in metric_table(SUMMARY_METRICS):
        lines.append(f"- `{key}`" + (f" [{unit}]" if unit else "") + f": {text}")
    lines += [
        "",
        "## Outputs",
        "",
        "Linear analysis report of law (6) on the reduced model (margins per mode, Bode, root",
        "loci, Nyquist, linear vs switching-plant step): [report-paper/report.html]"
        "(report-paper/report.html), [PDF](report-paper/report.pdf), "
        "[data.json](report-paper/data.json).",
        "",
        "| run | overview | energy | data |",
        "|---|---|---|---|",
    ]
    for s, k, _ in runs:
        d = f"{s}-{k}"
        lines.append(
            f"| {s} / {k} | [overview.png]({d}/overview.png) | [energy.png]({d}/energy.png) "
            f"| [trajectory.csv]({d}/trajectory.csv), [events.csv]({d}/events.csv), "
            f"[metrics.json]({d}/metrics.json) |"
        )
    return "\n".join(lines) + "\n"


def _cmd_demo(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    params = _load_params(args.params)
    out = Path(args.out)
    _check_out_dir(out)
    _note_existing(out)
    kinds = ("reduced",) if args.quick else MODELS
    jobs = [
        (s, k, c)
        for s in builtin_scenarios(params).values()
        if s.name in DEMO_SCENARIOS
        for k in kinds
        for c in (DEMO_CONTROLLERS if s.needs_controller else (None,))
    ]
    print(
        f"{PROG} demo: {len(jobs)} runs on parameter set {params.name!r} into {out}/",
        file=sys.stderr,
    )
    ensure_compiled()  # the progress notice, if the kernels are not cached
    done: list[tuple[str, str, dict[str, Any]]] = []
    tic = time.perf_counter()
    bar = tqdm(jobs, desc="demo", unit="run", file=sys.stderr, dynamic_ncols=True)
    for sc, kind, ctl in bar:
        label = sc.name if ctl is None else f"{sc.name}-{ctl}"
        bar.set_postfix_str(f"{label} / {kind}")
        r = run_simulation(sc, params, kind, out / f"{label}-{kind}", controller=ctl)
        done.append((label, kind, r))
    bar.close()
    from .reporting.controller_report import build_report  # matplotlib on demand

    print(
        f"{PROG} demo: linear analysis report of law (6) -> {out / 'report-paper'}/",
        file=sys.stderr,
    )
    try:
        build_report(controller="paper", params=params, model="reduced", out=out / "report-paper")
    except OSError as exc:
        raise RunError(f"cannot write the report to {out / 'report-paper'}: {exc}") from None
    except ValueError as exc:  # e.g. a parameter set on which law (6) cannot be analysed
        raise InputError(f"report-paper: {_msg(exc)}") from None
    except RuntimeError as exc:
        raise RunError(f"report-paper: {exc}") from None
    try:
        (out / "summary.md").write_text(_summary_md(done, params, args.quick), encoding="utf-8")
    except OSError as exc:
        raise RunError(f"cannot write {out / 'summary.md'}: {exc}") from None
    for _, _, r in done:
        print(_summary_line(r["metrics"], r["timing"]))
    print(f"done in {time.perf_counter() - tic:.1f} s; summary: {out / 'summary.md'}")
    for s, k, _ in done:
        print(f"  {out / f'{s}-{k}'}/")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from .reporting.controller_report import build_report  # matplotlib on demand

    _check_out_dir(Path(args.out))
    _note_existing(Path(args.out))
    params = _load_params(args.params)
    ensure_compiled()  # the progress notice, if the kernels are not cached
    try:
        rep = build_report(
            controller=args.controller,
            params=params,
            model=args.model,
            scenario=args.scenario,
            out=Path(args.out),
        )
    except (ValueError, KeyError) as exc:  # ControllerError, ScenarioError are ValueErrors
        raise InputError(_msg(exc)) from None
    except OSError as exc:
        raise RunError(f"cannot write the report to {args.out}: {exc}") from None
    except RuntimeError as exc:  # a simulation of the report failed (ZenoError included)
        raise RunError(f"report: {exc}") from None
    for f in rep.files:
        print(f)
    slip = rep.data["modes"]["slip"][rep.data["inputs"]["controller_name"]]
    print(f"judder threshold: {slip['judder']['summary']}")
    return 0


def _design_table(run: Any) -> list[str]:
    """The per-plant table of a design: achieved figures, stability, limiting (``*``)."""
    head = (
        f"{'#':>3} {'Ms':>6} {'Mt':>6} {'GM dB':>7} {'PM deg':>7} {'DM dB':>6} "
        f"{'wc rad/s':>9} {'stable':>6}  plant (* limits the design)"
    )
    lines = [head]
    for i, r in enumerate(run.plants):
        lines.append(
            f"{i:>3} {r.ms:>6.3f} {r.mt:>6.3f} {_fmt(r.gain_margin_db, '.1f'):>7} "
            f"{_fmt(r.phase_margin_deg, '.1f'):>7} {r.disk_margin_db:>6.1f} "
            f"{_fmt(r.crossover_rad_s, '.3g'):>9} {_fmt(r.stable):>6}  "
            f"{'*' if r.limiting else ' '}{r.plant}"
        )
    return lines


#: the linear figures printed beside the switching plant's metrics: (label, key of
#: ``DesignRun.worst()``, format)
DESIGN_FIGURES: tuple[tuple[str, str, str], ...] = (
    ("plants", "n_plants", "d"),
    ("max Ms", "ms_max", ".3f"),
    ("max Mt", "mt_max", ".3f"),
    ("min gain margin [dB]", "gain_margin_db_min", ".1f"),
    ("min phase margin [deg]", "phase_margin_deg_min", ".1f"),
    ("min disk margin [dB]", "disk_margin_db_min", ".1f"),
    ("crossover min [rad/s]", "crossover_rad_s_min", ".3g"),
    ("crossover max [rad/s]", "crossover_rad_s_max", ".3g"),
    ("all loops stable", "all_stable", ""),
)


def _side_by_side(run: Any, check: Any) -> list[str]:
    """The linear figures (worst over the plant set) beside the switching plant's engagement
    metrics per model."""
    from .design.from_spec import CHECK_METRICS

    w = run.worst()
    left = [f"linear ({run.method}, worst over the plant set)", ""]
    for label, key, spec in DESIGN_FIGURES:
        v = w[key]
        left.append(f"{label:<24}{_fmt(v, spec) if spec and v is not None else _fmt(v):>10}")
    right = [f"switching plant ({check.scenario}, {check.params})"]
    right.append(f"{'':<24}" + "".join(f"{r.model:>11}" for r in check.runs))
    for key in CHECK_METRICS:
        cells = [
            _fmt_metric(key, r.metrics.get(key)) if r.metrics is not None else "FAILED"
            for r in check.runs
        ]
        right.append(f"{key:<24}" + "".join(f"{c:>11}" for c in cells))
    n = max(len(left), len(right))
    left += [""] * (n - len(left))
    right += [""] * (n - len(right))
    width = max(len(x) for x in left) + 4
    return [f"{a:<{width}}{b}".rstrip() for a, b in zip(left, right, strict=True)]


def _cmd_design(args: argparse.Namespace) -> int:
    from .design.from_spec import DesignSpecError, design_from_spec, load_design_spec
    from .design.hinf import HinfSynthesisError, HinfTimeoutError

    out = Path(args.out)
    if out.suffix != ".toml":
        raise InputError(f"--out {out}: a controller file must end in .toml")
    if out.is_dir():
        raise InputError(f"--out {out} is an existing directory, not a controller file")
    try:
        spec = load_design_spec(args.spec)
    except FileNotFoundError as exc:
        raise InputError(f"design spec not found: {exc.filename or args.spec}") from None
    except (ValueError, OSError) as exc:
        raise InputError(f"design spec: {_msg(exc)}") from None
    ensure_compiled()  # the trajectory of the operating points is a simulation
    try:
        run = design_from_spec(args.method, spec, name=args.name or spec.name or out.stem)
    except (DesignSpecError, ControllerError) as exc:
        raise InputError(f"design spec {spec.source}: {_msg(exc)}") from None
    except HinfTimeoutError as exc:
        raise RunError(f"design {args.method}: {exc}") from None
    except ValueError as exc:  # an infeasible or unbounded specification, a bad option
        raise InputError(f"design {args.method} ({spec.source}): {_msg(exc)}") from None
    except (HinfSynthesisError, ZenoError, RuntimeError) as exc:
        raise RunError(f"design {args.method}: {exc}") from None
    print(f"design {args.method} from {spec.source}: {run.plant_set.summary()}")
    print("\n".join(_design_table(run)))
    print(textwrap.fill(run.result.summary(), width=100))
    if not run.met:
        print(f"WARNING: the specification is NOT met: {run.message}")
    ctrl = run.controller
    replaced = out.is_file()
    try:
        ctrl.to_toml(
            out,
            header=(
                f"Designed by `{PROG} design {args.method} --spec {spec.source}` (design spec "
                f"and achieved figures: the [design] table)."
            ),
        )
    except OSError as exc:
        raise RunError(f"cannot write {out}: {exc}") from None
    gains = (
        f"kp = {ctrl.kp:.4g} m s/rad, ki = {ctrl.ki:.4g} m/rad"
        if ctrl.law == "pi"
        else f"order {ctrl.lti().nstates}"
    )
    sampled = (
        f", sampled every {ctrl.sample_period_s:g} s with {ctrl.delay_samples} sample(s) delay"
        if ctrl.sample_period_s
        else ", continuous"
    )
    print(
        f"controller {ctrl.name!r} (law {ctrl.law!r}, {gains}{sampled}) written to {out}"
        + (" (replaced)" if replaced else "")
    )
    if args.no_check:
        return 0 if run.met else 1
    try:
        check = run.check()
    except (ValueError, OSError) as exc:
        raise InputError(f"design spec {spec.source}: check: {_msg(exc)}") from None
    print()
    print("\n".join(_side_by_side(run, check)))
    for r in check.runs:
        for w in dict.fromkeys(r.warnings):
            print(f"note ({r.model} model): {w}")
        for p in r.problems:
            msg = f"design {ctrl.name!r} on the switching plant, {r.model} model: {p}"
            print(f"!!! {msg}")
            print(f"{PROG}: WARNING: {msg}", file=sys.stderr)
    if not check.ok:
        print(
            f"!!! the controller file {out} was written, but the design FAILS on the switching "
            "plant: do not ship it as it is",
        )
        return 1
    return 0 if run.met else 1


def _value_text(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, PwlTable):
        n = len(v.x)
        if n == 1:
            return f"constant {v.y[0]:.6g}"
        xs = ", ".join(f"{a:.6g}" for a in v.x)
        ys = ", ".join(f"{b:.6g}" for b in v.y)
        return f"table ({n} points) x = [{xs}], y = [{ys}]"
    if isinstance(v, tuple):
        return "[" + ", ".join(f"{a:.6g}" if isinstance(a, float) else str(a) for a in v) + "]"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def _cmd_params_show(args: argparse.Namespace) -> int:
    p = _load_params(args.source)
    print(f"parameter set {p.name!r}: {p.description}")
    print(
        "SI units. frame: the shaft or body a value is referred to (engine, primary, "
        "secondary, wheel, vehicle; '-' = none)."
    )
    prov = p.provenance_dict()
    paths = field_paths()
    w_path = max(len(x) for x in paths)
    ind = " " * 6
    width = 100
    section = ""
    for path in paths:
        info = field_info(path)
        value = p.get(path)
        sec = path.split(".", 1)[0]
        if sec != section:
            print(f"\n[{sec}]")
            section = sec
        frame = f"(frame: {info['frame']})" if info["frame"] != "-" else ""
        if isinstance(value, PwlTable):
            what = (
                f"table {info['y_name']} [{info['y_unit']}] vs {info['x_name']} [{info['x_unit']}]"
            )
            print(f"  {path:<{w_path}} = {what}  {frame}".rstrip())
            lines = textwrap.wrap(
                _value_text(value), width, initial_indent=ind + "  ", subsequent_indent=ind + "  "
            )
            print("\n".join(lines))
        else:
            unit = "" if info["unit"] == "-" else info["unit"]
            print(f"  {path:<{w_path}} = {_value_text(value):>10} {unit:<10} {frame}".rstrip())
        text = info["description"]
        if args.provenance and path in prov:
            text += f" [source: {prov[path]}]"
        print(textwrap.fill(text, width, initial_indent=ind, subsequent_indent=ind))
    return 0


def _cmd_params_list(args: argparse.Namespace) -> int:
    for name in available_parameter_sets():
        p = _load_params(name)
        print(f"{name}: {p.description}")
    return 0


def _cmd_scenarios_list(args: argparse.Namespace) -> int:
    for name, sc in builtin_scenarios().items():
        print(f"{name} (gear {sc.gear}, t_end {sc.t_end:g} s, loop: {', '.join(sc.loops)})")
        for line in textwrap.wrap(sc.description, 92):
            print(f"    {line}")
    print("(or give --scenario FILE.toml; format: drivetrain_ctrl.scenarios module docstring)")
    return 0


def _cmd_study_run(args: argparse.Namespace) -> int:
    from .studies.runner import run_study
    from .studies.study import StudyError, load_study

    try:
        study = load_study(args.study)
    except StudyError as exc:
        raise InputError(_msg(exc)) from None
    print(study.summary())
    try:
        done = run_study(
            study,
            out=args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            chunk_size=args.chunk_size,
            progress=not args.no_progress,
        )
    except StudyError as exc:
        raise InputError(_msg(exc)) from None
    except OSError as exc:
        raise RunError(f"cannot write the results: {_msg(exc)}") from None
    print(done.summary())
    return 0


def _cmd_study_report(args: argparse.Namespace) -> int:
    from .reporting.study_report import StudyReportError, build_study_report

    try:
        rep = build_study_report(
            args.folder, out=args.out, worst=args.worst, resimulate=not args.no_resimulate
        )
    except StudyReportError as exc:
        raise InputError(_msg(exc)) from None
    except OSError as exc:
        raise RunError(f"cannot write the study report: {_msg(exc)}") from None
    for f in rep.files:
        print(f)
    return 0


def _weights(text: str) -> dict[str, float]:
    """``--weights KEY=W,...``: score key -> weight (checked by compare)."""
    out: dict[str, float] = {}
    for item in (x.strip() for x in text.split(",")):
        key, eq, val = item.partition("=")
        try:
            out[key.strip()] = float(val)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{item!r}: must read KEY=NUMBER") from None
        if not eq:
            raise argparse.ArgumentTypeError(f"{item!r}: must read KEY=NUMBER")
    return out


def _cmd_compare(args: argparse.Namespace) -> int:
    from .studies.compare import CompareError, compare

    _check_out_dir(Path(args.out))
    try:
        res = compare(
            controllers=args.controllers,
            scenarios=args.scenarios,
            model=args.model,
            params=args.params,
            weights=args.weights,
            t_end=args.t_end,
            workers=args.workers,
            progress=not args.no_progress,
            warn=lambda m: print(f"{PROG}: {m}", file=sys.stderr),
            open_loop=not args.no_open_loop,
        )
    except CompareError as exc:
        raise InputError(f"compare: {_msg(exc)}") from None
    try:
        rep = res.plot(Path(args.out))
    except OSError as exc:
        raise RunError(f"cannot write the comparison to {args.out}: {exc}") from None
    for line in res.data["verdict"]["reasoning"]:
        print(line)
    print(
        f"{len(res.data['runs']) * len(res.data['inputs']['scenarios'])} run(s) in "
        f"{res.wall_s:.1f} s on {res.workers} worker(s)"
    )
    for f in rep.files:
        print(f)
    return 0


# ------------------------------------------------------------------------------------------------
# parser
# ------------------------------------------------------------------------------------------------


def _positive_float(text: str) -> float:
    """An option's value: a finite number > 0 (:func:`~drivetrain_ctrl.core.validate.real_number`
    on the parsed text), else an argparse error naming the text."""
    try:
        return real_number("value", float(text), lo=0, lo_open=True)
    except ValueError:  # not a number (float), or not finite and > 0 (real_number)
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0") from None


def _out_dir(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: give an output directory")
    return text


def _positive_int(text: str) -> int:
    """An option's value: an integer >= 1, else an argparse error naming the text."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} must be an integer >= 1") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be an integer >= 1")
    return v


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``drivetrain-ctrl``."""
    ap = argparse.ArgumentParser(
        prog=PROG,
        description="Simulate a car dry-clutch drivetrain (exact switching, full/reduced model).",
    )
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", required=True)

    sp = sub.add_parser("simulate", help="simulate one scenario; write CSV, JSON and PNG files")
    sp.add_argument("--scenario", required=True, help="built-in scenario name or a .toml file")
    sp.add_argument("--model", choices=MODELS, default="full", help="model (default: full)")
    sp.add_argument(
        "--params",
        default=DEFAULT_PARAMS,
        help=f"parameter set name or .toml file (default: {DEFAULT_PARAMS})",
    )
    sp.add_argument(
        "--out", required=True, type=_out_dir, help="output directory (created if needed)"
    )
    sp.add_argument("--rtol", type=_positive_float, default=None, help="relative tolerance")
    sp.add_argument(
        "--t-end", type=_positive_float, default=None, help="end time [s] (default: scenario's)"
    )
    sp.add_argument(
        "--controller",
        default=None,
        help=f"closed loop: {_controller_names(', ')} or a controller .toml file "
        "(paper: law 6; default: open loop; paper-start needs one)",
    )
    sp.add_argument(
        "--loop",
        choices=LOOPS,
        default=None,
        help="closed: the controller drives the pedal; open: the scenario's pedal signal does "
        "(default: the scenario's own, closed if it has a [controller] table)",
    )
    sp.set_defaults(func=_cmd_simulate)

    rp = sub.add_parser(
        "report", help="linear analysis report of a controller: report.html, report.pdf, data.json"
    )
    rp.add_argument(
        "--controller",
        default="paper",
        help=f"{_controller_names(', ')} or a controller .toml file (default: paper)",
    )
    rp.add_argument("--params", default=DEFAULT_PARAMS, help="parameter set name or .toml file")
    rp.add_argument("--model", choices=MODELS, default="reduced", help="model (default: reduced)")
    rp.add_argument(
        "--scenario", default="paper-start", help="closed-loop scenario (default: paper-start)"
    )
    rp.add_argument(
        "--out", required=True, type=_out_dir, help="output directory (created if needed)"
    )
    rp.set_defaults(func=_cmd_report)

    dp = sub.add_parser("demo", help="run the built-in scenarios on both models; summary.md")
    dp.add_argument("--out", required=True, type=_out_dir, help="output directory")
    dp.add_argument("--quick", action="store_true", help="reduced model only (a few seconds)")
    dp.add_argument("--params", default=DEFAULT_PARAMS, help="parameter set name or .toml file")
    dp.set_defaults(func=_cmd_demo)

    pp = sub.add_parser("params", help="show or list parameter sets")
    psub = pp.add_subparsers(dest="params_command", metavar="ACTION", required=True)
    ps = psub.add_parser("show", help="print a parameter set with units and frames")
    ps.add_argument("source", nargs="?", default=DEFAULT_PARAMS, help="set name or .toml file")
    ps.add_argument("--provenance", action="store_true", help="also print the source of values")
    ps.set_defaults(func=_cmd_params_show)
    pl = psub.add_parser("list", help="list the built-in parameter sets")
    pl.set_defaults(func=_cmd_params_list)

    gp = sub.add_parser(
        "design",
        help="design a clutch controller from a design spec; write the controller file",
        description="Design a clutch controller from a design spec (TOML: the plant set, the "
        "bounds, the sampling; format: drivetrain_ctrl.design.from_spec), print the achieved "
        "figures per plant, write the controller file and run it on the switching plant.",
    )
    gp.add_argument("method", choices=("pi", "robust-pi", "pid", "hinf"), help="design method")
    gp.add_argument(
        "--spec",
        required=True,
        help="a design spec .toml file or a built-in one (robust-pi, hinf)",
    )
    gp.add_argument("--out", required=True, help="the controller file to write (.toml)")
    gp.add_argument(
        "--name", default=None, help="controller name (default: the spec's, else the file stem)"
    )
    gp.add_argument("--no-check", action="store_true", help="skip the run on the switching plant")
    gp.set_defaults(func=_cmd_design)

    sc = sub.add_parser("scenarios", help="list the built-in scenarios")
    ssub = sc.add_subparsers(dest="scenarios_command", metavar="ACTION", required=True)
    sl = ssub.add_parser("list", help="list the built-in scenarios")
    sl.set_defaults(func=_cmd_scenarios_list)

    cp = sub.add_parser(
        "compare",
        help="compare controllers on scenarios: compare.html, compare.pdf, data.json",
        description="Run every controller on every closed-loop scenario in parallel (Dask) and "
        "compare them: linear figures, engagement metrics with pass/fail, overlays, linear "
        "against nonlinear, and a ranking (drivetrain_ctrl.studies.compare).",
    )
    cp.add_argument(
        "--controllers",
        default="paper,pi,robust-pi,hinf",
        help=f"comma-separated: {_controller_names(', ')} or controller .toml files "
        "(default: paper,pi,robust-pi,hinf)",
    )
    cp.add_argument(
        "--scenarios",
        default="all",
        help="all (every built-in closed-loop scenario) or comma-separated names / .toml files",
    )
    cp.add_argument("--model", choices=MODELS, default="full", help="model (default: full)")
    cp.add_argument("--params", default=DEFAULT_PARAMS, help="parameter set name or .toml file")
    cp.add_argument(
        "--weights",
        type=_weights,
        default=None,
        help="score weights KEY=W,... (keys: engagement_time_s, clutch_energy_J, jerk_max_m_s3, "
        "tracking_rms_rpm, ms; default 1 each)",
    )
    cp.add_argument(
        "--t-end", type=_positive_float, default=None, help="end time [s] (default: scenario's)"
    )
    cp.add_argument(
        "--workers", type=_positive_int, default=None, help="worker processes (default: cores)"
    )
    cp.add_argument("--no-progress", action="store_true", help="no progress bar")
    cp.add_argument(
        "--no-open-loop",
        action="store_true",
        help="leave out the open-loop baseline (each scenario's driver's pedal, no controller)",
    )
    cp.add_argument(
        "--out", required=True, type=_out_dir, help="output directory (created if needed)"
    )
    cp.set_defaults(func=_cmd_compare)

    st = sub.add_parser("study", help="robustness studies: run a study file on Dask")
    stsub = st.add_subparsers(dest="study_command", metavar="ACTION", required=True)
    sr = stsub.add_parser(
        "run",
        help="run (or resume) a study into DIR/results/*.parquet",
        description="Run every sample x controller x scenario of a study file on a local Dask "
        "cluster (one worker process per core) or an existing scheduler; re-running resumes "
        "and computes only the missing rows (format: drivetrain_ctrl.studies.study).",
    )
    sr.add_argument("study", help="the study .toml file")
    sr.add_argument("--out", required=True, type=_out_dir, help="output directory")
    sr.add_argument(
        "--workers", type=_positive_int, default=None, help="worker processes (default: cores)"
    )
    sr.add_argument(
        "--scheduler", default=None, help="address of a running Dask scheduler (tcp://host:8786)"
    )
    sr.add_argument(
        "--chunk-size",
        type=_positive_int,
        default=None,
        help="runs per Dask task (default: sized to about 2 s of work each)",
    )
    sr.add_argument("--no-progress", action="store_true", help="no progress bar")
    sr.set_defaults(func=_cmd_study_run)
    srp = stsub.add_parser(
        "report",
        help="report of a study folder: report.html, report.pdf, data.json",
        description="Pass rates with confidence intervals, metric histograms and scatter plots, "
        "parameter sensitivities, the worst runs re-simulated, linear vs nonlinear figures and "
        "failure reasons of a study folder (drivetrain_ctrl.reporting.study_report).",
    )
    srp.add_argument("folder", help="the study folder (DIR of 'study run --out DIR')")
    srp.add_argument("--out", type=_out_dir, default=None, help="output directory (default: DIR)")
    srp.add_argument(
        "--worst", type=int, default=2, help="worst runs per controller to re-simulate (default 2)"
    )
    srp.add_argument(
        "--no-resimulate", action="store_true", help="do not re-simulate the worst runs"
    )
    srp.set_defaults(func=_cmd_study_report)
    return ap


def _format_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    line: str | None = None,
) -> str:
    return f"{PROG}: {category.__name__}: {message}\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``drivetrain-ctrl`` with ``argv`` (default: ``sys.argv[1:]``); returns the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(None if argv is None else list(argv))
    except SystemExit as exc:  # argparse: --help (0) or a usage error (2)
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 2)
    try:
        with warnings.catch_warnings():
            # a warning is a line of its own: the tool's name, the category and the message
            warnings.formatwarning = _format_warning
            return int(args.func(args))
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except RunError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into e.g. `head`: stop quietly
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
