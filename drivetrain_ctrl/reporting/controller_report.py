"""Controller report: rendering the analysis of a clutch controller next to its nonlinear run.

:func:`build_report` = :func:`~drivetrain_ctrl.reporting.controller_analysis.analyse_controller`
(the numbers) + :func:`render_report` (the files), which writes into ``out``:

* ``data.json``: every number behind every figure (keys sorted, no timestamps, paths or wall
  times: byte-identical for the same input);
* ``report.html``: self-contained (figures embedded as base64 PNG);
* ``report.pdf``: the same content drawn with matplotlib only (text pages, then the figures).

The files are written by :mod:`drivetrain_ctrl.reporting.document` (shared with the study report).

All figures are drawn from ``data`` only (:func:`make_figures`, in
:mod:`drivetrain_ctrl.reporting.figures`), so ``Report.plot()`` needs no re-computation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..control.laws import ControllerSpec
from ..plant.params import DrivetrainParams
from ..scenarios.scenario import Scenario
from ..sim.metrics import METRICS, metric_table
from .controller_analysis import (
    DISAGREEMENT_THRESHOLD,
    MARGIN_KEYS,
    MODELS,
    SLIP_DELAY_S,
    VISITED_MIN_S,
    _tf_text,
    analyse_controller,
)
from .document import html_page, pdf_blocks, write_data_json
from .figures import report_figures, write_report_pdf

__all__ = [
    "Report",
    "build_report",
    "make_figures",
    "MODELS",
    "MARGIN_KEYS",
    "SECTIONS",
    "SLIP_DELAY_S",
    "DISAGREEMENT_THRESHOLD",
]


#: section titles of the HTML and PDF reports, in order
SECTIONS: tuple[str, ...] = (
    "Model and operating points",
    "Transfer functions",
    "Bode diagrams of L, S, T",
    "Root loci",
    "Nyquist diagram",
    "Stability margins per mode",
    "Linear prediction vs switching plant",
    "Engagement metrics",
    "Where linear and nonlinear disagree",
)


# ---------------------------------------------------------------------------------------------
# result
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Report:
    """A built report: output directory ``out``, the JSON data ``data`` (as written to
    ``data.json``) and the files written (``data.json``, ``report.html``, ``report.pdf``)."""

    out: Path
    data: dict[str, Any]
    files: tuple[Path, ...]

    def plot(self) -> dict[str, Any]:
        """The report's figures (``{name: matplotlib Figure}``), drawn from ``data``."""
        return make_figures(self.data)


# ---------------------------------------------------------------------------------------------
# argument handling
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# numbers
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# operating points
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# linear vs nonlinear
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# builder
# ---------------------------------------------------------------------------------------------


def build_report(
    *,
    controller: str | Path | ControllerSpec = "paper",
    params: str | Path | DrivetrainParams | None = None,
    model: str = "reduced",
    scenario: str | Path | Scenario = "paper-start",
    out: str | Path,
) -> Report:
    """Analyse ``controller`` (:func:`~drivetrain_ctrl.reporting.controller_analysis.analyse_controller`:
    the same arguments) and render the report into ``out`` (:func:`render_report`): ``data.json``,
    ``report.html`` and ``report.pdf``.

    Raises ValueError naming the argument for a bad controller, model, parameter set or scenario.
    """
    data = analyse_controller(controller=controller, params=params, model=model, scenario=scenario)
    return render_report(data, out)


def render_report(data: dict[str, Any], out: str | Path) -> Report:
    """Write the report of analysis ``data`` into ``out`` (created): ``data.json`` (keys sorted,
    no timestamps, paths or wall times: byte-identical for the same data), ``report.html``
    (self-contained, figures embedded as base64 PNG) and ``report.pdf`` (text pages, then the
    figures). All figures are drawn from ``data`` only."""
    outp = Path(out)
    outp.mkdir(parents=True, exist_ok=True)
    files = [write_data_json(data, outp / "data.json")]
    figs = make_figures(data)
    fh = outp / "report.html"
    fh.write_text(_html(data, figs), encoding="utf-8")
    files.append(fh)
    fp = outp / "report.pdf"
    _pdf(data, figs, fp)
    files.append(fp)
    return Report(out=outp, data=data, files=tuple(files))


# ---------------------------------------------------------------------------------------------
# figures (from data only)
# ---------------------------------------------------------------------------------------------


def make_figures(data: dict[str, Any]) -> dict[str, Any]:
    """``{name: Figure}``: bode, root_locus, nyquist, step, engagement, lock (from ``data``;
    :func:`drivetrain_ctrl.reporting.figures.report_figures`)."""

    return dict(report_figures(data))


# ---------------------------------------------------------------------------------------------
# text content shared by HTML and PDF
# ---------------------------------------------------------------------------------------------


def _fmt(v: Any) -> str:
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


def _flat_items(d: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    """``(dotted key, value)`` of a nested table, in its order (the controller's design
    provenance)."""
    out: list[tuple[str, Any]] = []
    for k, v in d.items():
        if isinstance(v, dict):
            out += _flat_items(v, f"{prefix}{k}.")
        else:
            out.append((f"{prefix}{k}", v))
    return out


def _ranges(values: list[float], digits: str = ".4g") -> str:
    lo, hi = min(values), max(values)
    if format(lo, digits) == format(hi, digits):
        return format(lo, digits)
    return f"{lo:{digits}}-{hi:{digits}}"


def mode_table(visited: list[dict[str, Any]]) -> tuple[str, list[dict[str, Any]]]:
    """The table of visited modes (``data["visited_modes"]``, each with ``"modes"``: ``[element,
    mode]`` pairs and ``"segments"``: ``[table, segment index]`` pairs): modes that differ only in
    the segment of a piecewise-linear table merged into one row. Returns what every row shares (element modes ``"e=m"`` and table segments, as text) and
    the rows in order of total time held, each ``{"modes": the other element modes, "segments": the segments per
    table ("t 2-4, 7"), "duration_s": the total time [s], "frequencies": the natural frequencies
    [Hz] (damping) of the merged modes as ranges, "members": the number of modes merged}``. When
    the merged modes have different numbers of oscillatory poles, the frequencies are those of
    the longest held, so marked."""
    visited = [
        {**v, "modes": dict(map(tuple, v["modes"])), "segments": dict(map(tuple, v["segments"]))}
        for v in visited
    ]
    groups: dict[tuple[tuple[str, str], ...], list[dict[str, Any]]] = {}
    for v in visited:
        groups.setdefault(tuple(v["modes"].items()), []).append(v)
    keys = list(groups)
    elements = list(dict.fromkeys(e for k in keys for e, _ in k))
    common = [e for e in elements if len({dict(k).get(e) for k in keys}) == 1 and len(keys) > 1]
    all_tables = list(dict.fromkeys(t for v in visited for t in v.get("segments", {})))
    fixed = {
        t: seg.pop()
        for t in all_tables
        if len(seg := {v.get("segments", {}).get(t) for v in visited}) == 1 and len(visited) > 1
    }
    rows = []
    for key, members in groups.items():
        modes = ", ".join(f"{e}={m}" for e, m in key if e not in common) or "-"
        tables = [t for t in all_tables if t not in fixed]
        segs = []
        for t in tables:
            idx = sorted({int(v["segments"][t]) for v in members if t in v.get("segments", {})})
            if not idx:
                continue
            runs: list[str] = []
            start = prev = idx[0]
            for i in [*idx[1:], None]:
                if i is not None and i == prev + 1:
                    prev = i
                    continue
                runs.append(str(start) if start == prev else f"{start}-{prev}")
                if i is not None:
                    start = prev = i
            segs.append(f"{t} {', '.join(runs)}")
        longest = max(members, key=lambda v: v["duration_s"])
        counts = {len(v["natural_frequencies_hz"]) for v in members}
        if len(counts) == 1:
            n = counts.pop()
            fr = ", ".join(
                f"{_ranges([v['natural_frequencies_hz'][i] for v in members])} "
                f"({_ranges([v['damping'][i] for v in members], '.3g')})"
                for i in range(n)
            )
        else:
            fr = ", ".join(
                f"{f:.4g} ({z:.3g})"
                for f, z in zip(longest["natural_frequencies_hz"], longest["damping"], strict=True)
            ) + (" (the longest held of the merged modes; their numbers of oscillatory poles "
                 "differ)")  # fmt: skip
        rows.append(
            {
                "modes": modes,
                "segments": "; ".join(segs) or "-",
                "duration_s": sum(v["duration_s"] for v in members),
                "frequencies": fr or "none (no oscillatory pole)",
                "members": len(members),
            }
        )
    rows.sort(key=lambda r: -r["duration_s"])
    first = dict(keys[0]) if keys else {}
    same = [f"{e}={first[e]}" for e in common] + [f"{t} segment {i}" for t, i in fixed.items()]
    return ", ".join(same), rows


def _grid_change_text(rl: dict[str, Any]) -> str:
    """Where the stability changes first along a root-locus grid, in words."""
    ch = rl.get("grid_change")
    if ch is None:
        pts = rl.get("points") or [{"value": None}]
        return (
            f"the stability does not change on the grid ({_fmt(pts[0]['value'])} to "
            f"{_fmt(pts[-1]['value'])})"
        )
    return f"on the grid it becomes {ch['becomes']} between {_fmt(ch['from'])} and {_fmt(ch['to'])}"


def _sections(
    data: dict[str, Any],
) -> list[tuple[str, list[str], list[tuple[str, list[list[str]]]], list[str]]]:
    """``(title, paragraphs, tables, figure names)`` per section; a table is ``(caption, rows)``
    with the first row the header."""
    inp = data["inputs"]
    cname = inp["controller_name"]
    slip = data["modes"]["slip"][cname]
    lock = data["modes"]["lock"][cname]
    ops = data["operating_points"]
    out: list[tuple[str, list[str], list[tuple[str, list[list[str]]]], list[str]]] = []

    # 1 model and operating points
    ctrl_fields = {k: v for k, v in inp["controller"].items() if k != "design"}
    paras = [
        f"Model: {inp['model']}; parameter set: {inp['params']}; scenario: {inp['scenario']} "
        f"({inp['scenario_description']}); controller: {cname} "
        f"({', '.join(f'{k} = {_fmt(v)}' for k, v in sorted(ctrl_fields.items()) if v is not None)}).",
        f"Slip operating point: the simulated trajectory at t = {_fmt(ops['slip']['t_s'])} s "
        f"({_fmt(inp['slip_delay_s'])} s after the controller start).",
        "Lock operating point: "
        + (
            lock["operating_point_source"]
            if ops["lock"] is not None
            else f"not available: {lock['operating_point_source']}"
        )
        + ".",
    ]
    design = inp["controller"].get("design")
    if design:
        paras.insert(
            1,
            "Design (provenance: the controller file's [design] table): "
            + "; ".join(f"{k} = {_fmt(v)}" for k, v in _flat_items(design))
            + ".",
        )
    lk = ops["lock"]
    rows = [["", "slip"] + (["lock"] if lk is not None else [])]
    names = sorted(
        set(ops["slip"]["state"]) | set(ops["slip"]["inputs"]) | set(ops["slip"]["modes"])
    )
    for n in names:

        def g(o: dict[str, Any], n: str = n) -> str:
            for grp in ("state", "inputs", "modes"):
                if n in o[grp]:
                    return _fmt(o[grp][n])
            return "-"  # the model has no such quantity in that point's description

        rows.append([n, g(ops["slip"])] + ([g(lk)] if lk is not None else []))
    cert = ops["slip"]["certificate"]
    ttl = cert["time_to_lock_s"]
    ttl_text = (
        f"time to lock {_fmt(ttl)} s"
        if ttl is not None
        else "time to lock not available: the slip is not closing (the slip acceleration is "
        "zero or has the sign of the slip)"
    )
    paras.append(
        f"Slip certificate: slip speed {_fmt(cert['slip_speed_rad_s'])} rad/s, slip acceleration "
        f"{_fmt(cert['slip_accel_rad_s2'])} rad/s^2, {ttl_text} (a slip point is not an "
        "equilibrium)."
    )
    out.append((SECTIONS[0], paras, [("Operating points (SI units)", rows)], ["engagement"]))

    # 2 transfer functions
    rows = [["transfer function", "num / den"]]
    for k, d in sorted(slip["transfer_functions"].items()):
        rows.append([k, _tf_text(d)])
    out.append(
        (
            SECTIONS[1],
            [
                "Linearised clutch loop at the slip point (negative feedback, L = C P, "
                "S = 1/(1+L), T = L/(1+L)); the plant P includes the sign block, the actuator and "
                "the engine side."
            ],
            [("Transfer functions (coefficients in descending powers)", rows)],
            [],
        )
    )
    # 3 bode
    out.append(
        (
            SECTIONS[2],
            [
                "Frequency responses of the loop, sensitivity and complementary sensitivity at the slip point."
            ],
            [],
            ["bode"],
        )
    )
    # 4 root loci
    rl = slip["root_locus"]
    rg, rm = rl["gain"], rl["mu_slope"]
    jd = slip["judder"]
    paras = [
        f"Left: closed-loop poles over the controller gain {rg['parameter']} [{rg['unit']}] "
        f"(nominal {_fmt(rg.get('nominal'))}); {_grid_change_text(rg)}. Right: over the clutch "
        f"friction slope mu' [s/rad] of mu/mu0 (nominal at the slip point "
        f"{_fmt(rm.get('nominal'))}"
        + (f": not available, {rm['nominal_reason']}" if rm.get("nominal") is None else "")
        + f"); {_grid_change_text(rm)}"
        + (f" ({rm['span_reason']})" if rm.get("span_reason") else "")
        + ".",
        "Judder threshold (the first friction slope, from 0 towards a falling mu(slip), at which "
        "a pole of the re-linearised slip mode leaves the stable region; located by bracketing "
        f"and bisection): {jd['summary']}.",
    ]
    cf = jd.get("closed_form")
    if cf is not None:
        paras.append(
            f"Closed form (reduced model, linear.judder_threshold): mu' = "
            f"{_fmt(cf['mu_slope_crit'])} s/rad, {cf['which']} crossing near "
            f"{_fmt(cf['shuffle_frequency_hz'])} Hz (an approximation of the shuffle crossing)."
        )
    else:
        paras.append(f"Closed form: not available: {jd.get('closed_form_reason')}.")
    out.append((SECTIONS[3], paras, [], ["root_locus"]))
    # 5 nyquist
    ny = slip["nyquist"]
    out.append(
        (
            SECTIONS[4],
            [
                f"Clockwise encirclements of -1: N = {ny['encirclements']}; open-loop unstable "
                f"poles: P = {ny['open_loop_unstable_poles']}; closed-loop unstable poles Z = N + "
                f"P = {ny['closed_loop_unstable_poles']} (from the closed-loop poles: "
                f"{_fmt(ny.get('closed_loop_unstable_eig'))}).",
                "Convention, the same for continuous and sampled loops: open-loop poles on the "
                "stability boundary (an integrator at s = 0 or z = 1; here "
                f"{ny.get('boundary_poles', 0)}) count as stable, the contour passing them on the "
                "unstable side (python-control's indentation to the right). Left: the whole "
                "curve, low frequencies included, with the radius compressed beyond |L| = 1; "
                "right: a linear window around -1.",
            ],
            [],
            ["nyquist"],
        )
    )
    # 6 margins
    rows = [["figure", "slip", "lock"]]
    for k in MARGIN_KEYS:

        def cell(e: dict[str, Any], k: str = k) -> str:
            v = e.get(k)
            if v is None:
                return (
                    "not available: " + str(e.get("reasons", {}).get(k, "undefined"))
                    if e is slip
                    else "not available: the clutch loop is open (above)"
                )
            if k == "closed_loop_poles":
                return "; ".join(f"{p['real']:.4g}{p['imag']:+.4g}j" for p in v)
            if isinstance(v, list):
                return ", ".join(_fmt(x) for x in v)
            return _fmt(v)

        rows.append([k, cell(slip), cell(lock)])
    paras = [f"Lock mode: {lock['reasons'][MARGIN_KEYS[0]]}."]
    for m in lock.get("shuffle_modes") or []:
        paras.append(
            f"Locked driveline shuffle mode: {m['natural_frequency_hz']:.4g} Hz natural, "
            f"{m['damped_frequency_hz']:.4g} Hz damped, damping ratio {m['damping']:.4g}."
        )
    for el, b in sorted((lock.get("breakaway_margins") or {}).items()):
        paras.append(
            f"Torque margin to breakaway of the {el}: {_fmt(b['margin'])} N m (static capacity "
            f"{_fmt(b['capacity'])} N m, carried {_fmt(b['torque'])} N m)."
        )
    common, mrows = mode_table(data.get("visited_modes", []))
    vrows = [["mode (elements that differ)", "table segments", "time held [s]",
              "natural frequencies [Hz] (damping)"]]  # fmt: skip
    for r in mrows:
        vrows.append([r["modes"], r["segments"], _fmt(r["duration_s"]), r["frequencies"]])
    paras.append(
        "Every mode the engagement run holds for at least "
        f"{VISITED_MIN_S * 1e3:g} ms, linearised at the middle of its longest interval; modes "
        "that differ only in the segment of a piecewise-linear table (spring pieces, pedal map) "
        "are one row, with their times added and the range of their frequencies"
        + (f". In every one: {common}." if common else ".")
    )
    out.append(
        (
            SECTIONS[5],
            paras,
            [(f"Margins, controller {cname}", rows), ("Natural frequencies in every mode", vrows)],
            ["lock"],
        )
    )
    # 7 step comparison
    rows = [
        [
            "step",
            "size [rpm]",
            "peak linear [rpm]",
            "peak diff [rpm]",
            "RMS diff [rpm]",
            "rel. peak diff",
            "agree",
        ]
    ]
    for name, s in sorted(data["linear_vs_nonlinear"]["steps"].items()):
        rows.append(
            [
                name,
                _fmt(s["step_rpm"]),
                _fmt(s["peak_linear_rpm"]),
                _fmt(s["peak_difference_rpm"]),
                _fmt(s["rms_difference_rpm"]),
                _fmt(s["relative_peak_difference"]),
                _fmt(s["agree"]),
            ]
        )
    out.append(
        (
            SECTIONS[6],
            [
                "A step of the engine-speed reference at the slip operating point: the linear "
                "closed loop (control.forced_response) against the difference of two nonlinear "
                "simulations (stepped minus nominal reference) started from the same state."
            ],
            [("Step comparison (engine speed)", rows)],
            ["step"],
        )
    )
    # 8 engagement metrics: every key with its unit and definition (sim.metrics.METRICS)
    em = data["engagement_metrics"]
    rows = [["metric", "value", "unit", "definition"]] + [
        [
            k,
            _fmt(em[k]) if not isinstance(em[k], list) else "; ".join(map(str, em[k])) or "-",
            unit or "-",
            text,
        ]
        for k, unit, text in metric_table(k for k in METRICS if k in em)
    ]
    out.append(
        (
            SECTIONS[7],
            [
                "The figures of merit of the nonlinear run, under the names of metrics.json (the "
                "definitions are those of drivetrain_ctrl.sim.metrics.METRICS)."
            ],
            [("Engagement metrics", rows)],
            [],
        )
    )
    # 9 statement
    out.append((SECTIONS[8], list(data["linear_vs_nonlinear"]["statements"]), [], []))
    return out


def _html(data: dict[str, Any], figs: dict[str, Any]) -> str:
    inp = data["inputs"]
    return html_page(
        f"Clutch controller report: {inp['controller_name']}",
        f"Clutch controller report: {inp['controller_name']} on the {inp['model']} model, "
        f"scenario {inp['scenario']}",
        _sections(data),
        figs,
    )


def _pdf_blocks(data: dict[str, Any], figs: dict[str, Any]) -> list[tuple[Any, ...]]:
    """The PDF's content in reading order: each section's text, tables and then its figures
    (:func:`~drivetrain_ctrl.reporting.document.pdf_blocks`)."""
    inp = data["inputs"]
    return pdf_blocks(
        f"Clutch controller report: {inp['controller_name']} on the {inp['model']} model, "
        f"scenario {inp['scenario']}",
        _sections(data),
        figs,
    )


def _pdf(data: dict[str, Any], figs: dict[str, Any], path: Path) -> None:
    inp = data["inputs"]
    write_report_pdf(
        _pdf_blocks(data, figs),
        path,
        header=f"drivetrain_ctrl controller report: {inp['controller_name']}, {inp['model']} "
        f"model, {inp['scenario']}",
    )
