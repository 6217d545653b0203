"""The comparison report: figures, a self-contained HTML page, a PDF and ``data.json``.

Renders the ``data`` of :func:`~drivetrain_ctrl.studies.compare.compare` (nothing is computed
here): the Bode overlay of L and S of every controller at its nominal slip point (the slip mode;
in lock mode the clutch loop is open and has no Bode diagram, which the page says), one figure of
time responses per scenario (engine and primary-shaft speed, pedal, clutch torque, vehicle
acceleration, with the engine-speed reference; every controller in each, named in the legend,
and the open-loop baseline, a driver's pedal, in black),
and the tables: verdict (with the reasoning), linear figures (nominal and per scenario; the
worst case and nominal figures over the design's plant set, recomputed, beside the recorded
ones; the certified friction-slope sector), switching-plant metrics with pass/fail (the open-loop baseline's rows beside), linear
against nonlinear, and what was left out. The page, the PDF's blocks and ``data.json`` are
written by :mod:`drivetrain_ctrl.reporting.document`, as for the other reports.

:func:`write_compare_report` writes ``compare.html`` (figures as embedded PNGs, tables sortable
by a click on a column heading: a few lines of plain JavaScript), ``compare.pdf`` and
``data.json`` (keys sorted, no NaN: the same data gives the same bytes).

Check the page in a browser without console errors (what ``tests/integration/test_compare.py``
does when Chromium is installed)::

    chromium --headless --disable-gpu --enable-logging=stderr --v=0 \\
        --dump-dom DIR/compare.html > /dev/null
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .document import Section, data_json_text, html_page, pdf_blocks, write_data_json
from .figures import write_report_pdf

__all__ = [
    "CompareReport",
    "compare_figures",
    "compare_sections",
    "data_json_text",
    "write_compare_report",
]

#: the rows of a time-response figure: (series key, axis label)
_ROWS: tuple[tuple[str, str], ...] = (
    ("omega_engine_rpm", "engine (solid), primary\n(dashed), reference [rpm]"),
    ("pedal_mm", "pedal x_c [mm]"),
    ("clutch_torque_Nm", "clutch torque [N m]"),
    ("vehicle_accel_m_s2", "vehicle accel. [m/s^2]"),
)
#: the metrics shown in the switching-plant table
_METRIC_COLUMNS: tuple[str, ...] = (
    "lockup_time_s",
    "engagement_time_s",
    "clutch_energy_J",
    "engine_speed_min_rpm",
    "engine_speed_max_rpm",
    "tracking_rms_rpm",
    "lurch_rad_s2",
    "jerk_max_m_s3",
    "n_lock_events",
    "rollback_m",
    "energy_residual_rel",
)
_MARGINS: tuple[tuple[str, str], ...] = (
    ("gain_margin_db", "GM [dB]"),
    ("phase_margin_deg", "PM [deg]"),
    ("delay_margin_s", "delay margin [s]"),
    ("disk_margin_db", "disk GM [dB]"),
    ("disk_margin_deg", "disk PM [deg]"),
    ("ms", "Ms"),
    ("mt", "Mt"),
    ("crossover_rad_s", "crossover [rad/s]"),
    ("bandwidth_rad_s", "bandwidth [rad/s]"),
    ("stable", "stable"),
)
_DESIGN: tuple[tuple[str, str], ...] = (
    ("n_plants", "plants"),
    ("ms_max", "Ms max"),
    ("mt_max", "Mt max"),
    ("gain_margin_db_min", "GM min [dB]"),
    ("phase_margin_deg_min", "PM min [deg]"),
    ("disk_margin_db_min", "disk GM min [dB]"),
    ("crossover_rad_s_min", "crossover min [rad/s]"),
    ("crossover_rad_s_max", "crossover max [rad/s]"),
    ("all_stable", "all stable"),
)

Table = tuple[str, list[list[str]]]

#: the name of the open-loop baseline in the figures' legends and the tables
BASELINE = "open loop (driver's pedal)"


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _color(i: int) -> str:
    return f"C{i % 10}"


def compare_figures(data: Mapping[str, Any]) -> dict[str, Any]:
    """The figures of the report (matplotlib :class:`~matplotlib.figure.Figure` s, no pyplot):
    ``bode_slip`` and ``time_<scenario>`` per scenario."""
    from matplotlib.figure import Figure

    ctrls = list(data["inputs"]["controllers"])
    figs: dict[str, Any] = {}
    fig = Figure(figsize=(8.0, 7.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    drawn = 0
    for i, c in enumerate(ctrls):
        slip = (data["nominal_linear"].get(c) or {}).get("slip") or {}
        bd = slip.get("bode")
        if not bd:
            continue
        drawn += 1
        w = bd["omega_rad_s"]
        lab = c if slip.get("stable") is not False else f"{c} (unstable)"
        axes[0].semilogx(w, bd["L_db"], color=_color(i), label=lab)
        axes[1].semilogx(w, bd["L_deg"], color=_color(i), label=lab)
        axes[2].semilogx(w, bd["S_db"], color=_color(i), label=lab)
    axes[0].axhline(0.0, color="k", lw=0.5)
    axes[0].set_ylabel("|L| [dB]")
    axes[1].set_ylabel("phase L [deg]")
    axes[2].set_ylabel("|S| [dB]")
    axes[2].set_xlabel("frequency [rad/s]")
    for ax in axes:
        ax.grid(True, which="both", lw=0.3)
    if drawn:
        axes[0].legend(fontsize=8, loc="best")
    axes[0].set_title(
        f"Slip mode: loop L and sensitivity S at the nominal slip point "
        f"({data['definitions']['nominal_scenario']}, {data['inputs']['model']} model)",
        fontsize=10,
    )
    figs["bode_slip"] = fig
    for s in data["inputs"]["scenarios"]:
        fig = Figure(figsize=(8.0, 9.0), layout="constrained")
        axes = fig.subplots(len(_ROWS), 1, sharex=True)
        ref: list[float] | None = None
        for i, c in enumerate(ctrls):
            rec = data["runs"][c][s]
            ser = rec.get("series")
            if not ser:
                continue
            t = ser["t_s"]
            for ax, (key, _) in zip(axes, _ROWS, strict=True):
                ax.plot(t, ser[key], color=_color(i), lw=1.1, label=c)
            axes[0].plot(t, ser["omega_primary_rpm"], color=_color(i), lw=0.9, ls="--")
            ref = ser.get("omega_ref_rpm")
        base = (data.get("open_loop") or {}).get(s) or {}
        bser = base.get("series")
        if bser:
            tb = bser["t_s"]
            for ax, (key, _) in zip(axes, _ROWS, strict=True):
                ax.plot(tb, bser[key], color="k", lw=1.0, ls="-.", label=BASELINE)
            axes[0].plot(tb, bser["omega_primary_rpm"], color="0.5", lw=0.8, ls="--")
        if ref is not None:  # the scenario's, the same for every controller
            axes[0].plot(t, ref, color="k", lw=0.9, ls=":", label="reference")
        for ax, (_, label) in zip(axes, _ROWS, strict=True):
            ax.set_ylabel(label, fontsize=8)
            ax.grid(True, lw=0.3)
        axes[-1].set_xlabel("time [s]")
        axes[0].legend(fontsize=8, loc="best", title="controller", title_fontsize=8)
        axes[0].set_title(f"Scenario {s} ({data['inputs']['model']} model)")
        figs[f"time_{s}"] = fig
    return figs


def compare_sections(data: Mapping[str, Any]) -> list[Section]:
    """``(title, paragraphs, tables, figure names)`` of the report, in reading order; a table is
    ``(caption, rows)`` with the first row the header."""
    inp, dfn = data["inputs"], data["definitions"]
    ctrls, scens = list(inp["controllers"]), list(inp["scenarios"])
    out: list[Section] = []
    paras = [
        f"Controllers: {', '.join(ctrls)}. Scenarios: {', '.join(scens)}. Model: {inp['model']}; "
        f"parameter set: {inp['params']}"
        + (f"; horizon cut to {inp['t_end_s']:g} s" if inp.get("t_end_s") else "")
        + ".",
        "Criteria per run: " + "; ".join(dfn["criteria"].values()) + ".",
    ]
    for s in scens:
        paras.append(f"{s}: {inp['scenario_descriptions'][s]}")
    if inp.get("open_loop"):
        paras.append(
            f"Baseline, {BASELINE}: {dfn.get('open_loop')}. In the time responses in black "
            "(dash-dotted), in the metrics table below the controllers."
        )
    tables: list[Table] = []
    if data["invalid"]:
        rows = [["kind", "name", "left out because"]]
        rows += [[p["kind"], p["name"], p["reason"]] for p in data["invalid"]]
        tables.append(("Left out of the comparison", rows))
    out.append(("Inputs", paras, tables, []))

    w = inp["weights"]
    v = data["verdict"]
    rows = [["rank", "controller", "criteria passed", "score"] + [f"{k} (w {w[k]:g})" for k in w]]
    for r in v["ranking"]:
        rows.append(
            [
                str(r["rank"]),
                r["controller"],
                f"{r['criteria_passed']}/{r['criteria_applicable']}",
                f"{r['score']:.3f}",
            ]
            + [f"{r['mean_ratio'][k]:.3f}" for k in w]
        )
    paras = [
        "Ranked by criteria passed (more first), then by the weighted score (lower first): per "
        "score key and scenario the value divided by the best valid controller's, capped at "
        f"{dfn['ratio_cap']:g} (an undefined value counts as the cap), averaged over the "
        "scenarios; the score is the weighted mean over the keys (1 = best everywhere; ms: the "
        "nominal slip loop's peak sensitivity).",
        *v["reasoning"],
    ]
    out.append(("Verdict", paras, [("Ranking", rows)], []))

    rows = [["controller"] + [lab for _, lab in _MARGINS]]
    for c in ctrls:
        slip = (data["nominal_linear"].get(c) or {}).get("slip")
        if slip is None:
            why = (data["nominal_linear"].get(c) or {}).get("slip_reason") or "no slip loop"
            rows.append([c] + [why] + ["-"] * (len(_MARGINS) - 1))
        else:
            rows.append([c] + [_fmt(slip.get(k)) for k, _ in _MARGINS])
    drows = [["controller", "plant set", "figures"] + [lab for _, lab in _DESIGN]]
    sets: list[str] = []
    for c in ctrls:
        d = data["design"].get(c) or {}
        if d.get("plant_set") and d["plant_set"] not in sets:
            sets.append(d["plant_set"])
        tag = f"set {sets.index(d['plant_set']) + 1}" if d.get("plant_set") else "-"
        if d.get("worst") is None:
            drows.append([c, tag, d.get("reason") or "not checked"] + ["-"] * len(_DESIGN))
        else:
            for what, fig in (("worst case", d["worst"]), ("nominal", d.get("nominal"))):
                drows.append([c, tag, what] + [_fmt((fig or {}).get(k)) for k, _ in _DESIGN])
        rec = d.get("recorded")
        if rec:
            drows.append(
                [c, "as designed", f"recorded ({d.get('method')})"]
                + [_fmt(rec.get(k)) for k, _ in _DESIGN]
            )
    set_paras = [f"Set {i + 1}: {t}" for i, t in enumerate(sets)] + [
        f"{c}: checked over {(data['design'].get(c) or {}).get('plant_set_source')}."
        for c in ctrls
        if (data["design"].get(c) or {}).get("plant_set_source")
    ]
    crows = [
        [
            "controller",
            "certified mu' [s/rad]",
            "sector [N m s/rad]",
            "linear limit mu' [s/rad]",
            "judder threshold [s/rad]",
            "certified / threshold",
        ]
    ]
    for c in ctrls:
        slip = (data["nominal_linear"].get(c) or {}).get("slip") or {}
        ce = slip.get("certificate")
        if ce is None:
            crows.append([c, "not computed"] + ["-"] * 4)
        elif ce.get("mu_slope_certified") is None:
            crows.append([c, ce.get("reason") or "-"] + ["-"] * 4)
        else:
            jt = ce.get("judder_closed_form")
            jt = ce.get("judder_numeric") if jt is None else jt
            sec = ce.get("sector_N_m_s_rad") or [None, None]
            crows.append(
                [
                    c,
                    _fmt(ce["mu_slope_certified"]),
                    f"[{_fmt(sec[0])}, {_fmt(sec[1])}]",
                    _fmt(ce.get("mu_slope_linear")),
                    _fmt(jt),
                    _fmt(ce.get("ratio")),
                ]
            )
    fr = "/".join(f"{f:g}" for f in dfn["slip_fractions"])
    srows = [["controller", "scenario", "t slip point [s]", "slip [rad/s]"]]
    srows[0] += [lab for _, lab in _MARGINS] + [f"stable at slip x {fr}"]
    for c in ctrls:
        for s in scens:
            lin = (data["runs"][c][s].get("linear") or {}).get("slip")
            if lin is None:
                srows.append([c, s, "-", "-"] + ["-"] * (len(_MARGINS) + 1))
                continue
            op = lin["operating_point"]
            later = "/".join(_fmt(p.get("stable")) for p in lin.get("later_points", []))
            srows.append(
                [c, s, _fmt(op["t_s"]), _fmt(op["slip_speed_rad_s"])]
                + [_fmt(lin.get(k)) for k, _ in _MARGINS]
                + [later or "-"]
            )
    lrows = [
        [
            "controller",
            "scenario",
            "t lock point [s]",
            "shuffle [Hz]",
            "shuffle damping",
            "breakaway margin [N m]",
            "clutch capacity [N m]",
        ]
    ]
    for c in ctrls:
        for s in scens:
            lk = (data["runs"][c][s].get("linear") or {}).get("lock")
            if lk is None:
                lrows.append([c, s] + ["-"] * 5)
                continue
            first = lk["shuffle_modes"][0] if lk["shuffle_modes"] else {}
            lrows.append(
                [
                    c,
                    s,
                    _fmt(lk["t_s"]),
                    _fmt(first.get("natural_frequency_hz")),
                    _fmt(first.get("damping")),
                    _fmt(lk["clutch_breakaway_margin_Nm"]),
                    _fmt(lk["clutch_capacity_Nm"]),
                ]
            )
    paras = [
        f"Slip mode: the clutch loop linearised at each run's slip point ({dfn['slip_delay_s']:g} s "
        f"after the controller start); the nominal point is that of {dfn['nominal_scenario']}. "
        "Lock mode: the clutch loop is open (x_c does not change the torque of a stuck clutch): "
        "no margins and no Bode diagram; at the lock point (the run "
        f"{dfn['lock_delay_s']:g} s after lock-up) the locked driveline's lowest "
        "shuffle mode and the clutch's torque margin to breakaway.",
        "Design plant set: each controller checked here over its design's plant set (rebuilt "
        "from the controller file's design spec; a controller without one over the default set, "
        f"the plants of the built-in design spec {dfn.get('default_plant_set')!r}): the worst case "
        "over every plant and over the nominal-parameter plants; a designed controller's "
        "figures as its file records them ([design.achieved]) beside them.",
        *set_paras,
        f"Certified sector: {dfn.get('certificate')}; beside it the linear limit (a constant "
        "slope) and the judder threshold, at the nominal slip point.",
    ]
    out.append(
        (
            "Linear figures",
            paras,
            [
                ("Nominal slip loop", rows),
                ("Design plant set: worst case and nominal (recomputed), and as recorded", drows),
                ("Certified friction-slope sector (nominal slip loop)", crows),
                ("Slip loop per scenario", srows),
                ("Lock mode per scenario", lrows),
            ],
            ["bode_slip"],
        )
    )

    crit = list(dfn["criteria"])
    rows = [["controller", "scenario", "status"] + list(_METRIC_COLUMNS) + crit]
    for c in ctrls:
        for s in scens:
            rec = data["runs"][c][s]
            m = rec.get("metrics") or {}
            cr = rec.get("criteria") or {}
            rows.append(
                [c, s, rec.get("status") or "-"]
                + [_fmt(m.get(k)) for k in _METRIC_COLUMNS]
                + ["n/a" if cr.get(k) is None else ("pass" if cr[k] else "FAIL") for k in crit]
            )
    baseline = data.get("open_loop") or {}
    for s in scens:
        rec = baseline.get(s)
        if rec is None:
            continue
        m = rec.get("metrics") or {}
        cr = rec.get("criteria") or {}
        rows.append(
            [BASELINE, s, rec.get("status") or "-"]
            + [_fmt(m.get(k)) for k in _METRIC_COLUMNS]
            + ["n/a" if cr.get(k) is None else ("pass" if cr[k] else "FAIL") for k in crit]
        )
    errs = [
        f"{c} on {s}: {data['runs'][c][s]['error']}"
        for c in ctrls
        for s in scens
        if data["runs"][c][s].get("error")
    ] + [f"{BASELINE} on {s}: {r['error']}" for s, r in baseline.items() if r.get("error")]
    out.append(
        (
            "Switching plant",
            ["Engagement metrics (definitions: the simulation page) and the criteria.", *errs],
            [("Metrics and criteria", rows)],
            [f"time_{s}" for s in scens],
        )
    )
    rows = [["controller", "scenario", "disagree", "statement"]]
    for c in ctrls:
        for s in scens:
            a = data["runs"][c][s].get("linear_vs_nonlinear") or {}
            rows.append([c, s, _fmt(a.get("disagree")), a.get("statement") or "-"])
    out.append(
        (
            "Linear against nonlinear",
            [
                f"They disagree when {dfn['disagree']}. Causes named from the run after the slip "
                "point: lock-up, sign switch of the slip, saturation at a stroke limit, "
                f"operating-point drift (slip speed changing by more than "
                f"{100 * dfn['drift_threshold']:g} % within {dfn['drift_window_s']:g} s)."
            ],
            [("Prediction and result", rows)],
            [],
        )
    )
    return out


_STYLE = (
    "<style>body{font-family:sans-serif;max-width:1200px;margin:auto;padding:0 1em}"
    "table{border-collapse:collapse;margin:0.5em 0;display:block;overflow-x:auto}"
    "td,th{border:1px solid #999;padding:2px 6px;font-size:0.85em;text-align:left}"
    "th{background:#eee;cursor:pointer;user-select:none}img{max-width:100%}"
    "caption{text-align:left;font-weight:bold;padding:0.3em 0}</style>"
)
#: click a heading to sort a table by that column (numbers as numbers; again to reverse)
_SORT_JS = """<script>
document.querySelectorAll("table.sortable").forEach(function (table) {
  var heads = table.querySelectorAll("th");
  heads.forEach(function (th, col) {
    th.title = "click to sort";
    th.addEventListener("click", function () {
      var body = table.tBodies[0];
      var rows = Array.prototype.slice.call(body.rows);
      var asc = th.getAttribute("data-order") !== "asc";
      heads.forEach(function (h) { h.removeAttribute("data-order"); });
      th.setAttribute("data-order", asc ? "asc" : "desc");
      rows.sort(function (a, b) {
        var x = a.cells[col] ? a.cells[col].textContent : "";
        var y = b.cells[col] ? b.cells[col].textContent : "";
        var p = parseFloat(x), q = parseFloat(y);
        var r = (!isNaN(p) && !isNaN(q)) ? p - q : x.localeCompare(y);
        return asc ? r : -r;
      });
      rows.forEach(function (r) { body.appendChild(r); });
    });
  });
});
</script>"""


def _title(data: Mapping[str, Any]) -> str:
    return f"Controller comparison ({data['inputs']['model']} model)"


@dataclass(frozen=True)
class CompareReport:
    """The files written by :func:`write_compare_report`: ``html``, ``pdf`` (None: not
    written), ``data``."""

    html: Path
    pdf: Path | None
    data: Path

    @property
    def files(self) -> tuple[Path, ...]:
        return tuple(p for p in (self.html, self.pdf, self.data) if p is not None)


def write_compare_report(
    data: Mapping[str, Any], out: str | Path, *, pdf: bool = True
) -> CompareReport:
    """Write ``compare.html``, ``compare.pdf`` (unless ``pdf`` is False: the slowest part) and
    ``data.json`` of comparison ``data`` into folder ``out`` (created); returns their paths
    (``pdf`` None when not written)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_data_json(data, out / "data.json")
    figs = compare_figures(data)
    sections = compare_sections(data)
    page = html_page(
        _title(data), _title(data), sections, figs, style=_STYLE, sortable=True, script=_SORT_JS
    )
    (out / "compare.html").write_text(page, encoding="utf-8")
    if not pdf:
        return CompareReport(out / "compare.html", None, out / "data.json")
    blocks = pdf_blocks(_title(data), sections, figs)
    write_report_pdf(blocks, out / "compare.pdf", header="drivetrain_ctrl controller comparison")
    return CompareReport(out / "compare.html", out / "compare.pdf", out / "data.json")
