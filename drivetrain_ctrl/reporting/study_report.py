"""Study report: the figures and files of a robustness study's analysis.

:func:`build_study_report` = :func:`~drivetrain_ctrl.studies.analysis.analyse_study` (the
numbers) + :func:`render_study_report` (the files), which writes into the study folder (or
``out``):

* ``data.json``: every number behind every figure (keys sorted, no timestamps, paths of the
  output or wall times: byte-identical for the same folder);
* ``report.html``: self-contained (figures embedded as base64 PNG);
* ``report.pdf``: the same content drawn with matplotlib only.

The files are written by :mod:`drivetrain_ctrl.reporting.document` (shared with the controller
report); every figure is drawn from ``data`` only (:func:`make_figures`). Failed runs (status
``failed``: no metrics) are left out of the histograms, scatter plots and correlations and
counted in the failure section.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..studies.analysis import StudyReportError, analyse_study
from .document import Section, html_page, pdf_blocks, write_data_json
from .figures import write_report_pdf

__all__ = [
    "STUDY_SECTIONS",
    "StudyReport",
    "StudyReportError",
    "build_study_report",
    "make_figures",
    "render_study_report",
]

#: section titles of the HTML and PDF study reports, in order
STUDY_SECTIONS: tuple[str, ...] = (
    "Study",
    "Pass rates",
    "Metric distributions",
    "Metrics versus parameters",
    "Which parameters matter most",
    "Worst runs, re-simulated",
    "Linear versus nonlinear",
    "Failure reasons",
)
#: at most this many metrics (the criteria's first) in the scatter-plot grid
SCATTER_METRICS: int = 4
_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
           "#bcbd22", "#17becf", "#d62728")  # fmt: skip


@dataclass(frozen=True)
class StudyReport:
    """A written study report: the folder ``out``, the analysis ``data`` (as in ``data.json``)
    and the files written (``data.json``, ``report.html``, ``report.pdf``)."""

    out: Path
    data: dict[str, Any]
    files: tuple[Path, ...]

    def plot(self) -> dict[str, Any]:
        """The report's figures (``{name: matplotlib Figure}``), drawn from ``data``."""
        return make_figures(self.data)


def build_study_report(
    folder: str | Path,
    *,
    out: str | Path | None = None,
    worst: int = 2,
    resimulate: bool = True,
) -> StudyReport:
    """Analyse study folder ``folder`` (:func:`~drivetrain_ctrl.studies.analysis.analyse_study`:
    ``worst`` runs per controller re-simulated unless ``resimulate`` is False) and write the
    report into ``out`` (default: ``folder``). Raises
    :class:`~drivetrain_ctrl.studies.analysis.StudyReportError` naming the folder when it holds
    no study results."""
    analysis = analyse_study(folder, worst=worst, resimulate=resimulate)
    return render_study_report(analysis.data, Path(folder) if out is None else out)


def render_study_report(data: dict[str, Any], out: str | Path) -> StudyReport:
    """Write the report of analysis ``data`` into ``out`` (created): ``data.json``,
    ``report.html``, ``report.pdf``."""
    outp = Path(out)
    outp.mkdir(parents=True, exist_ok=True)
    files = [write_data_json(data, outp / "data.json")]
    figs = make_figures(data)
    sections = _sections(data)
    title = f"Study report: {data['study']['name']}"
    heading = (
        f"Study report: {data['study']['name']} ({data['rows']['total']} runs on the "
        f"{data['study']['model']} model)"
    )
    fh = outp / "report.html"
    fh.write_text(html_page(title, heading, sections, figs), encoding="utf-8")
    files.append(fh)
    fp = outp / "report.pdf"
    write_report_pdf(pdf_blocks(heading, sections, figs), fp, header=f"drivetrain_ctrl {title}")
    files.append(fp)
    return StudyReport(out=outp, data=data, files=tuple(files))


# -- figures (from data only) -------------------------------------------------------------------
def _arr(v: list[Any]) -> Any:
    return np.array([math.nan if x is None else float(x) for x in v], dtype=float)


def _color(data: dict[str, Any], group: str) -> str:
    return _COLORS[data["groups"].index(group) % len(_COLORS)]


def _label(data: dict[str, Any], m: str) -> str:
    u = data["metric_units"].get(m, "")
    return f"{m} [{u}]" if u and u != "-" else m


def _grid(n: int, ncol: int, size: tuple[float, float]) -> tuple[Any, list[Any]]:
    from matplotlib.figure import Figure

    nrow = max(1, math.ceil(n / ncol))
    fig = Figure(figsize=(size[0], size[1] * nrow), layout="constrained")
    axs = np.atleast_1d(fig.subplots(nrow, ncol, squeeze=False)).ravel().tolist()
    for ax in axs[n:]:
        ax.set_visible(False)
    return fig, axs[:n]


def _fig_pass_rates(data: dict[str, Any]) -> Any:
    from matplotlib.figure import Figure

    rates = data["pass_rates"]
    crit = list(data["study"]["criteria"])
    cats = ["all criteria", *crit]
    fig = Figure(figsize=(10, 3.2 + 0.25 * len(cats)), layout="constrained")
    ax = fig.subplots()
    width = 0.8 / max(1, len(rates))
    for j, r in enumerate(rates):
        entries = [r] + [r["criteria"][c] for c in crit if c in r["criteria"]]
        y = np.array([math.nan if e["rate"] is None else e["rate"] for e in entries])
        lo = np.array([math.nan if e["ci_low"] is None else e["ci_low"] for e in entries])
        hi = np.array([math.nan if e["ci_high"] is None else e["ci_high"] for e in entries])
        x = np.arange(len(entries)) + (j - (len(rates) - 1) / 2) * width
        ax.bar(x, y, width, color=_color(data, r["group"]), label=f"{r['group']} (n = {r['n']})")
        ax.errorbar(x, y, yerr=[y - lo, hi - y], fmt="none", ecolor="k", capsize=3, lw=1)
    ax.set_xticks(np.arange(len(cats)), cats, rotation=15, ha="right", fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("pass rate")
    ax.set_title(f"Pass rates with {100 * data['confidence']:g} % Wilson intervals")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def _fig_histograms(data: dict[str, Any]) -> Any:
    hs = data["histograms"]
    names = [m for m in data["metrics"] if hs[m]["edges"] is not None]
    fig, axs = _grid(len(names), 3, (11, 2.6))
    for ax, m in zip(axs, names, strict=True):
        h = hs[m]
        edges = _arr(h["edges"])
        for g, e in h["groups"].items():
            if e["n"]:
                ax.stairs(e["counts"], edges, color=_color(data, g), label=g)
        ax.set_xlabel(_label(data, m), fontsize=8)
        ax.set_ylabel("runs", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    if axs:
        axs[0].legend(fontsize=7)
    return fig


def _scatter_metrics(data: dict[str, Any]) -> list[str]:
    crit = [c.split(" ")[0] for c in data["study"]["criteria"]]
    order = [m for m in dict.fromkeys([*crit, *data["metrics"]]) if m in data["metrics"]]
    return order[:SCATTER_METRICS]


def _fig_scatter(data: dict[str, Any]) -> Any:
    from matplotlib.figure import Figure

    pts = data["points"]
    ms = _scatter_metrics(data)
    ps = data["parameters"]
    fig = Figure(figsize=(2.8 * len(ps) + 1, 2.4 * len(ms) + 0.6), layout="constrained")
    axs = fig.subplots(len(ms), len(ps), squeeze=False)
    groups = np.array(pts["group"], dtype=object)
    passed = np.array(pts["pass"], dtype=bool)
    for i, m in enumerate(ms):
        y = _arr(pts["metrics"][m])
        for j, p in enumerate(ps):
            ax = axs[i, j]
            x = _arr(pts["params"][p])
            for g in data["groups"]:
                for ok, mk in ((True, "o"), (False, "x")):
                    sel = (groups == g) & (passed == ok) & np.isfinite(x) & np.isfinite(y)
                    if np.any(sel):
                        ax.scatter(x[sel], y[sel], s=9, marker=mk, color=_color(data, g),
                                   label=f"{g}, {'pass' if ok else 'fail'}", alpha=0.7)  # fmt: skip
            if i == len(ms) - 1:
                ax.set_xlabel(p, fontsize=8)
            if j == 0:
                ax.set_ylabel(_label(data, m), fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(True, alpha=0.3)
    h, lab = axs[0, 0].get_legend_handles_labels()
    if h:
        fig.legend(h, lab, loc="outside upper center", ncol=min(4, len(h)), fontsize=7)
    return fig


def _fig_sensitivity(data: dict[str, Any]) -> Any:
    sens = data["sensitivity"]
    fig, axs = _grid(len(sens), 2, (11, 0.6 + 0.45 * max(1, len(data["parameters"])) * 2))
    for ax, s in zip(axs, sens, strict=True):
        params = [r["parameter"] for r in s["ranking"]][::-1]
        mets = s["ranked_on"]
        h = 0.8 / max(1, len(mets))
        for k, m in enumerate(mets):
            v = [s["metrics"][m][p]["sobol_first"] for p in params]
            y = np.arange(len(params)) + (k - (len(mets) - 1) / 2) * h
            ci = [s["metrics"][m][p].get("sobol_first_conf") for p in params]
            ax.barh(y, [0.0 if x is None else x for x in v], h, label=f"S1 {m}",
                    color=_COLORS[k % len(_COLORS)],
                    xerr=[math.nan if c is None or x is None else c for x, c in zip(v, ci, strict=True)],
                    error_kw={"ecolor": "0.3", "capsize": 2, "lw": 0.8})  # fmt: skip
            rho = [s["metrics"][m][p]["spearman"] for p in params]
            ax.plot([math.nan if r is None else abs(r) for r in rho], y, "k|", ms=8)
        ax.set_yticks(np.arange(len(params)), params, fontsize=8)
        ax.set_xlim(0, 1)
        ax.set_xlabel(
            f"S1, RBD-FAST (bars, {100 * data['confidence']:g} % interval); |Spearman rho| (ticks)",
            fontsize=8,
        )
        ax.set_title(s["group"], fontsize=9)
        ax.grid(True, axis="x", alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    return fig


def _fig_worst(data: dict[str, Any]) -> Any:
    from matplotlib.figure import Figure

    rows = [r for r in data["worst"]["rows"] if r["trace"] is not None]
    fig = Figure(figsize=(3.6 * len(rows) + 0.8, 7.5), layout="constrained")
    axs = fig.subplots(3, len(rows), sharex="col", squeeze=False)
    for j, r in enumerate(rows):
        tr = r["trace"]
        t = _arr(tr["t_s"])
        ax = axs[:, j]
        ax[0].plot(t, _arr(tr["omega_engine_rpm"]), label="engine")
        ax[0].plot(t, _arr(tr["omega_driven_rpm"]), label=tr["driven_state"].removeprefix("omega_"))
        if tr["omega_ref_rpm"] is not None:
            ax[0].plot(t, _arr(tr["omega_ref_rpm"]), "k--", lw=0.8, label="reference")
        ax[0].set_title(f"{r['key']}\n{', '.join(r['missed']) or 'all criteria met'}", fontsize=7)
        ax[1].plot(t, _arr(tr["clutch_torque_Nm"]), color="C2")
        ax[2].plot(t, _arr(tr["vehicle_accel_m_s2"]), color="C3")
        ax[2].set_xlabel("t [s]", fontsize=8)
        lt = r["metrics"].get("lockup_time_s")
        for a in ax:
            if lt is not None:
                a.axvline(lt, color="k", ls=":", lw=0.8)
            a.grid(True, alpha=0.3)
            a.tick_params(labelsize=7)
        if j == 0:
            ax[0].set_ylabel("speed [rpm]", fontsize=8)
            ax[1].set_ylabel("clutch torque [N m]", fontsize=8)
            ax[2].set_ylabel("vehicle accel. [m/s^2]", fontsize=8)
            ax[0].legend(fontsize=7)
    return fig


def _fig_linear(data: dict[str, Any]) -> Any:
    from matplotlib.figure import Figure

    lin = data["linear"]
    pts = data["points"]
    cols = lin["plotted"]
    outs = [m for m in lin["outcomes"] if m != "pass"]
    fig = Figure(figsize=(3.4 * max(1, len(outs)) + 1, 2.5 * len(cols) + 0.6), layout="constrained")
    axs = fig.subplots(len(cols), max(1, len(outs)), squeeze=False)
    passed = np.array(pts["pass"], dtype=bool)
    for i, c in enumerate(cols):
        x = _arr(pts["lin"][c])
        for j, m in enumerate(outs):
            ax = axs[i, j]
            y = _arr(pts["metrics"][m])
            for ok, color, name in ((True, "tab:green", "pass"), (False, "tab:red", "fail")):
                sel = (passed == ok) & np.isfinite(x) & np.isfinite(y)
                if np.any(sel):
                    ax.scatter(x[sel], y[sel], s=9, color=color, alpha=0.7, label=name)
            rhos = [
                f"{g['group']}: {g['correlations'][c][m]['spearman']:.2f}"
                for g in lin["groups"]
                if g["correlations"][c][m]["spearman"] is not None
            ]
            ax.set_title("rho " + ", ".join(rhos) if rhos else "rho n/a", fontsize=7)
            ax.set_xlabel(c, fontsize=8)
            ax.set_ylabel(_label(data, m), fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(True, alpha=0.3)
    h, lab = axs[0, 0].get_legend_handles_labels()
    if h:
        axs[0, 0].legend(fontsize=7)
    return fig


def _fig_failures(data: dict[str, Any]) -> Any:
    from matplotlib.figure import Figure

    f = data["failures"]
    crit = list(data["study"]["criteria"])
    fig = Figure(figsize=(10, 3.0 + 0.3 * (len(crit) + len(f["runs"]))), layout="constrained")
    ax = fig.subplots()
    cats = ["did not finish", *crit]
    h = 0.8 / max(1, len(f["criteria"]))
    for k, g in enumerate(f["criteria"]):
        v = [g["not_finished"], *(g["criteria"].get(c, 0) for c in crit)]
        y = np.arange(len(cats)) + (k - (len(f["criteria"]) - 1) / 2) * h
        ax.barh(y, v, h, color=_color(data, g["group"]), label=f"{g['group']} ({g['runs']} runs)")
    ax.set_yticks(np.arange(len(cats)), cats, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("runs")
    ax.set_title("Runs that did not finish, and runs missing each criterion")
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def make_figures(data: dict[str, Any]) -> dict[str, Any]:
    """``{name: Figure}`` from ``data`` only: pass_rates, histograms, scatter, sensitivity,
    failures; worst (if a worst run was re-simulated) and linear (if the table has ``lin:``
    columns)."""
    draw = {
        "pass_rates": _fig_pass_rates,
        "histograms": _fig_histograms,
        "scatter": _fig_scatter,
        "sensitivity": _fig_sensitivity,
        "worst": _fig_worst,
        "linear": _fig_linear,
        "failures": _fig_failures,
    }
    figs = {name: draw[name](data) for name in make_figure_names(data)}
    return figs


# -- text ---------------------------------------------------------------------------------------
def _fmt(v: Any, digits: str = ".4g") -> str:
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return format(v, digits)
    return str(v)


def _pct(e: dict[str, Any]) -> str:
    if e["rate"] is None:
        return "n/a"
    return f"{100 * e['rate']:.1f} % [{100 * e['ci_low']:.1f}, {100 * e['ci_high']:.1f}]"


def _s1(e: dict[str, Any]) -> str:
    """A Sobol index with its confidence half-width (``n/a`` where undefined)."""
    if e["sobol_first"] is None:
        return "n/a"
    conf = e.get("sobol_first_conf")
    return f"{e['sobol_first']:.2f}" + ("" if conf is None else f" +/- {conf:.2f}")


def _sections(data: dict[str, Any]) -> list[Section]:
    """``(title, paragraphs, tables, figure names)`` of every section, in order."""
    s = data["study"]
    rows = data["rows"]
    figs = make_figure_names(data)
    out: list[Section] = []

    # 1 study
    prm = [["parameter", "distribution", "arguments (SI)"]] + [
        [p, d.get("dist", "?"), ", ".join(f"{k} = {_fmt(v)}" for k, v in d.items() if k != "dist")]
        for p, d in (s.get("parameters") or {}).items()
    ]
    paras = [
        f"Study {s['name']}: {s['samples']} samples ({s['method']}, seed {s['seed']}) x "
        f"controllers {', '.join(s['controllers'])} x scenarios {', '.join(s['scenarios'])} on "
        f"the {s['model']} model, parameter set {s['params']}.",
        f"Criteria: {'; '.join(s['criteria']) or 'none'}. The table holds {rows['total']} of "
        f"{rows['expected']} runs: {rows['ok']} finished, {rows['failed']} failed, "
        f"{rows['passed']} met every criterion.",
    ]
    if rows["total"] < rows["expected"]:
        paras.append(
            "The study is incomplete (re-run 'drivetrain-ctrl study run' to resume): every figure "
            "below is of the runs present."
        )
    out.append((STUDY_SECTIONS[0], paras, [("Uncertain parameters", prm)], []))

    # 2 pass rates
    conf = f"{100 * data['confidence']:g} %"
    t = [["group", "runs", "passed", f"pass rate [{conf} Wilson interval]"]]
    t += [[r["group"], str(r["n"]), str(r["passed"]), _pct(r)] for r in data["pass_rates"]]
    ct = [["group", *s["criteria"]]]
    ct += [
        [r["group"], *(_pct(r["criteria"][c]) for c in s["criteria"])] for r in data["pass_rates"]
    ]
    out.append(
        (
            STUDY_SECTIONS[1],
            [
                f"Share of runs meeting every criterion, per controller and scenario, with the "
                f"two-sided {conf} Wilson score interval (scipy.stats.binomtest(k, n)."
                "proportion_ci(method='wilson')). A run that failed counts as not passed; each "
                "criterion is judged on its own from its metric."
            ],
            [("Pass rates", t)] + ([("Pass rate per criterion", ct)] if s["criteria"] else []),
            ["pass_rates"],
        )
    )

    # 3 histograms
    ht = [["metric", "group", "runs", "undefined", "min", "median", "max"]]
    for m in data["metrics"]:
        for g, e in data["histograms"][m]["groups"].items():
            ht.append([_label(data, m), g, str(e["n"]), str(e["undefined"]), _fmt(e["min"]),
                       _fmt(e["median"]), _fmt(e["max"])])  # fmt: skip
    out.append(
        (
            STUDY_SECTIONS[2],
            [
                "Histograms of every metric kept, per group, on shared bins. A run that failed, "
                "or whose figure is undefined (e.g. no lock-up), is not in the histogram; it is "
                "counted as undefined."
            ],
            [("Metric summary", ht)],
            [f for f in ("histograms",) if f in figs],
        )
    )

    # 4 scatter
    out.append(
        (
            STUDY_SECTIONS[3],
            [
                f"Metrics ({', '.join(_scatter_metrics(data)) or 'none'}: the criteria's first) "
                "against each uncertain parameter; colour: group, o: passed every criterion, "
                "x: did not. Failed runs have no metrics and are not drawn."
            ],
            [],
            [f for f in ("scatter",) if f in figs],
        )
    )

    # 5 sensitivity
    m = data["methods"]
    paras = [
        "Global sensitivity of each metric to each uncertain parameter, per group, from the runs "
        f"with a defined value (at least {m['min_rows']}): Spearman's rank correlation rho "
        "(scipy.stats.spearmanr; monotone influence, with its sign) and the first-order Sobol "
        "index S1 = Var(E[Y | X_i]) / Var(Y), the share of the metric's variance explained by "
        "the parameter alone, estimated from the given samples by RBD-FAST "
        "(SALib.analyze.rbd_fast: the runs ordered by the parameter as in Plischke 2010, S1 the "
        f"share of the output's spectrum in the first {m['sobol_harmonics']} harmonics, fewer "
        "for few runs, bias-corrected after Tissot and Prieur 2012), with SALib's "
        f"{conf} confidence half-width (+/-, a normal approximation over "
        f"{m['sobol_resamples']} bootstrap draws of half the runs, seed {m['sobol_seed']}).",
        "Limits: the samples are Monte Carlo, Latin hypercube, Sobol points or a grid, not a "
        "Saltelli design, so only first-order indices can be estimated: interactions between "
        "parameters and total-effect indices are not resolved; the estimate assumes "
        "independently drawn parameters (true of the study's sampling); the bias correction "
        "can put a parameter without influence below 0; a response that jumps with "
        "the parameter (a threshold, or a grid parameter with few values) spreads over more "
        "harmonics than are summed, so its S1 is underestimated; with few runs the interval is "
        "wide (from draws of half the runs, on the wide side), and the index says little where "
        "it spans 0 to 1. Rows with an undefined metric "
        "are left out, which biases a metric undefined in part of the space. Parameters are "
        "ranked by their largest S1 over the criteria's metrics.",
    ]
    tables = []
    for sv in data["sensitivity"]:
        rt = [["rank", "parameter", "largest S1", "on metric", "largest |rho|"]]
        rt += [[str(k + 1), r["parameter"], _fmt(r["sobol_first_max"], ".3f"),
                _fmt(r["on_metric"]), _fmt(r["abs_spearman_max"], ".3f")]
               for k, r in enumerate(sv["ranking"])]  # fmt: skip
        tables.append((f"Ranking, {sv['group']}", rt))
        dt = [["metric", *(r["parameter"] for r in sv["ranking"])]]
        for met in sv["ranked_on"]:
            dt.append([met, *(
                f"rho {_fmt(sv['metrics'][met][r['parameter']]['spearman'], '.2f')}, "
                f"S1 {_s1(sv['metrics'][met][r['parameter']])}"
                for r in sv["ranking"])])  # fmt: skip
        tables.append((f"Rank correlation and S1, {sv['group']}", dt))
    out.append((STUDY_SECTIONS[4], paras, tables, [f for f in ("sensitivity",) if f in figs]))

    # 6 worst
    w = data["worst"]
    if w["reason"]:
        paras = [f"No worst runs: {w['reason']}."]
        tables = []
    else:
        paras = [
            "Per controller, the finished runs that miss their criteria the most (the largest "
            "relative violation (value - threshold) / |threshold| of any criterion; an undefined "
            "metric is the worst), re-simulated with the row's parameters "
            "(studies.case.simulate_case): engine and driven-plate speed, clutch torque and "
            "vehicle acceleration (the dotted line: lock-up). 'Reproduced': the re-simulation "
            "gives the table's criteria metrics."
        ]
        wt = [["run", "violation", "missed", "parameters", "reproduced"]]
        for r in w["rows"]:
            rs = r["resimulated"] or {}
            rep = _fmt(rs.get("reproduces_table")) if rs.get("error") is None else rs["error"]
            wt.append([r["key"], _fmt(r["score"], ".3g"), "; ".join(r["missed"]) or "-",
                       ", ".join(f"{k} = {_fmt(v)}" for k, v in r["params"].items()), rep])  # fmt: skip
        tables = [("Worst runs", wt)]
    out.append((STUDY_SECTIONS[5], paras, tables, [f for f in ("worst",) if f in figs]))

    # 7 linear vs nonlinear
    lin = data["linear"]
    if not lin["available"]:
        out.append((STUDY_SECTIONS[6], [f"Not available: {lin['reason']}."], [], []))
    else:
        lt = [["linear figure", "group", *lin["outcomes"]]]
        for g in lin["groups"]:
            for c in lin["columns"]:
                lt.append([c, g["group"], *(
                    f"{_fmt(g['correlations'][c][o]['spearman'], '.2f')} (n {g['correlations'][c][o]['n']})"
                    for o in lin["outcomes"])])  # fmt: skip
        out.append(
            (
                STUDY_SECTIONS[6],
                [
                    "How well the paired linear figures of the slip-mode loop at each sample's "
                    f"parameters ({', '.join(lin['columns'])}) predict the nonlinear outcome: "
                    "Spearman's rank correlation per group and over all runs with "
                    f"{', '.join(lin['outcomes'])} (pass as 0/1), over the finished runs (n/a: "
                    "a constant figure or fewer runs than needed); the figure draws "
                    f"{', '.join(lin['plotted'])} and colours each run by pass (green) or fail "
                    "(red)."
                ],
                [("Rank correlation, linear figure vs nonlinear outcome", lt)],
                [f for f in ("linear",) if f in figs],
            )
        )

    # 8 failures
    f = data["failures"]
    st = [["status", "runs"]] + [[k, str(v)] for k, v in f["status_counts"].items()]
    tables = [("Runs by status", st)]
    if f["runs"]:
        rt = [["reason (numbers as #)", "runs", "per group", "example"]]
        rt += [[e["reason"], str(e["count"]), ", ".join(f"{g}: {n}" for g, n in e["by_group"].items()),
                e["example_key"]] for e in f["runs"]]  # fmt: skip
        tables.append(("Runs that did not finish, by reason", rt))
    if s["criteria"]:
        mt = [["group", "runs", "did not finish", *s["criteria"]]]
        mt += [[g["group"], str(g["runs"]), str(g["not_finished"]),
                *(str(g["criteria"].get(c, 0)) for c in s["criteria"])] for g in f["criteria"]]  # fmt: skip
        tables.append(("Runs missing each criterion", mt))
    out.append(
        (
            STUDY_SECTIONS[7],
            [
                "Why runs failed: those that did not finish (a simulator error, invalid "
                "parameter values or an early stop), counted by their reason, and the runs "
                "missing each criterion (a run can miss several)."
                + ("" if f["runs"] else " Every run finished.")
            ],
            tables,
            ["failures"],
        )
    )
    return out


def make_figure_names(data: dict[str, Any]) -> list[str]:
    """The names of the figures :func:`make_figures` draws for ``data`` (without drawing them)."""
    names = ["pass_rates"]
    if any(data["histograms"][m]["edges"] is not None for m in data["metrics"]):
        names.append("histograms")
    if data["parameters"] and _scatter_metrics(data):
        names.append("scatter")
    if data["parameters"] and data["sensitivity"] and data["metrics"]:
        names.append("sensitivity")
    if any(r["trace"] is not None for r in data["worst"]["rows"]):
        names.append("worst")
    if data["linear"]["available"] and [m for m in data["linear"]["outcomes"] if m != "pass"]:
        names.append("linear")
    names.append("failures")
    return names
