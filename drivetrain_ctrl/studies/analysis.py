"""The numbers of a study report: pass rates, distributions, sensitivities, worst runs, failures.

:func:`analyse_study` reads a study folder (``DIR/study.json`` and the results table of
:func:`~drivetrain_ctrl.studies.runner.read_results`) and returns a :class:`StudyAnalysis` whose
``data`` (a JSON-ready dict, deterministic for the same folder: no timestamps, no paths, no
wall times) holds every number behind every figure of the report
(:mod:`drivetrain_ctrl.reporting.study_report`). Rows are grouped by controller and scenario.

* **Pass rates** with a two-sided 95 % Wilson score interval
  (``scipy.stats.binomtest(k, n).proportion_ci(method="wilson")``), per group and per criterion;
  a run that failed counts as not passed. Each criterion is judged from its metric column
  (status ``ok`` and :meth:`Criterion.check <drivetrain_ctrl.studies.study.Criterion.check>`),
  so a run missing one criterion still counts for the others it meets.
* **Distributions**: a histogram of each metric per group (shared bin edges), over the runs
  whose metric is defined (a failed run or an undefined figure, e.g. no lock-up, is left out
  and counted).
* **Global sensitivity** of each metric to each uncertain parameter, per group: Spearman's rank
  correlation (``scipy.stats.spearmanr``) and the first-order Sobol index
  S_i = Var(E[Y | X_i]) / Var(Y) estimated from the given samples by SALib's RBD-FAST analyzer
  (``SALib.analyze.rbd_fast``: Plischke's given-data ordering, Tarantola et al. 2006,
  Plischke 2010, with the Tissot & Prieur 2012 bias correction) with its bootstrap confidence
  half-width (see :func:`first_order_index`). The studies' samples are Monte Carlo, Latin
  hypercube, Sobol points or grids, not a Saltelli design, so only first-order indices from
  given data apply: interactions are not resolved and the parameters must be drawn
  independently (they are).
* **Worst runs**: per controller the runs that miss their criteria the most (the largest
  relative violation ``(value - threshold) / |threshold|`` of any criterion; an undefined
  metric counts as the worst), re-simulated through
  :func:`~drivetrain_ctrl.studies.case.simulate_case` with the row's parameters; their engine and
  driven-plate speeds, clutch torque and vehicle acceleration are kept at 100 Hz.
* **Linear versus nonlinear**: Spearman's correlation of every paired linear figure of the table
  (columns ``lin:<name>``: margins, Ms, judder margin) with the lock-up time, the peak jerk and
  the pass flag, per group and over all runs; a table without ``lin:`` columns (a folder written
  before they existed) says so.
* **Failures**: the runs that did not finish, counted by reason (numbers in the messages
  replaced by ``#`` so that one cause is one line), and the runs missing each criterion.
"""

from __future__ import annotations

import json
import math
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ..core.serialize import json_ready
from ..core.units import RAD_S_TO_RPM
from ..sim.metrics import METRICS, state_accelerations
from .case import simulate_case
from .study import Criterion, Study, StudyError, _parse_criterion

__all__ = [
    "CONFIDENCE",
    "LINEAR_OUTCOMES",
    "LINEAR_PLOTTED",
    "MIN_ROWS",
    "SOBOL_HARMONICS",
    "SOBOL_RESAMPLES",
    "SOBOL_SEED",
    "StudyAnalysis",
    "StudyReportError",
    "analyse_study",
    "first_order_index",
    "wilson_interval",
]

F64 = NDArray[np.float64]

#: confidence level of the pass-rate intervals
CONFIDENCE: float = 0.95
#: fewest runs with a defined value for a rank correlation or a Sobol index
MIN_ROWS: int = 10
#: harmonics of RBD-FAST (SALib's default ``M``; fewer for few runs, see :func:`first_order_index`)
SOBOL_HARMONICS: int = 10
#: bootstrap resamples of the Sobol index's confidence interval (SALib's default)
SOBOL_RESAMPLES: int = 100
#: seed of the Sobol index's tie order and bootstrap: the same table gives the same data.json
SOBOL_SEED: int = 23
#: metrics the paired linear figures are correlated with (those the study keeps), and ``pass``
LINEAR_OUTCOMES: tuple[str, ...] = ("lockup_time_s", "jerk_max_m_s3")
#: the paired linear figures drawn against the outcomes (those present), the others are tabled
LINEAR_PLOTTED: tuple[str, ...] = (
    "lin:Ms",
    "lin:disk_margin",
    "lin:gain_margin",
    "lin:phase_margin_deg",
    "lin:judder_margin",
)
#: sampling rate [Hz] of the re-simulated worst runs' traces
TRACE_RATE_HZ: float = 100.0
#: the prefixes of a parameter column and of a paired linear figure
PARAM, LIN = "param:", "lin:"


class StudyReportError(ValueError):
    """A folder the report cannot read (the message names the folder or file and why)."""


@dataclass(frozen=True)
class StudyAnalysis:
    """The analysis of a study folder: ``data`` (JSON-ready, every number behind every figure;
    see the module docstring), the ``table`` it was computed from and the ``folder``."""

    folder: Path
    data: dict[str, Any]
    table: pd.DataFrame

    def plot(self) -> dict[str, Any]:
        """The report's figures (``{name: matplotlib Figure}``), drawn from ``data``."""
        from ..reporting.study_report import make_figures

        return make_figures(self.data)


# -- statistics ---------------------------------------------------------------------------------
def wilson_interval(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The two-sided Wilson score interval of a proportion with ``k`` successes in ``n`` trials
    (``scipy.stats.binomtest``); (nan, nan) for n = 0."""
    from scipy.stats import binomtest

    if n == 0:
        return (math.nan, math.nan)
    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return (float(ci.low), float(ci.high))


def _bins_for(n: int) -> int:
    return int(min(50, max(2, round(math.sqrt(n)))))


def first_order_index(x: Any, y: Any, *, seed: int = SOBOL_SEED) -> tuple[float, float]:
    """First-order Sobol index S = Var(E[y | x]) / Var(y) of one input ``x`` from given samples,
    and the half-width of its confidence interval at :data:`CONFIDENCE`.

    Computed by ``SALib.analyze.rbd_fast.analyze`` (RBD-FAST from given data: the runs are
    ordered by ``x`` in Plischke's 2010 zig-zag, S is the share of the output's periodogram in
    the first M harmonics, bias-corrected after Tissot & Prieur 2012, so it may be
    negative for an input without influence; the interval is SALib's: a normal approximation
    over :data:`SOBOL_RESAMPLES` bootstrap draws of half the runs). M = :data:`SOBOL_HARMONICS`,
    or fewer for few runs so that each half-size bootstrap draw still has more than M
    frequencies: M = min(10, floor(floor(n / 2) / 2) - 1). The rows are first put in an order
    drawn from ``seed``: RBD-FAST sorts by ``x``, and the tied runs of a discrete or grid
    parameter would otherwise stay in table order, which follows the other parameters. The
    result depends only on the data and ``seed``. (NaN, NaN) for fewer than :data:`MIN_ROWS`
    runs, non-finite values, or a constant ``x`` or ``y``; a NaN half-width when the bootstrap
    draws are degenerate.
    """
    from SALib.analyze import rbd_fast

    xa = np.asarray(x, dtype=float)
    ya = np.asarray(y, dtype=float)
    n = ya.shape[0] if ya.ndim == 1 else 0
    if n < MIN_ROWS or xa.shape != ya.shape:
        return (math.nan, math.nan)
    if not (np.all(np.isfinite(xa)) and np.all(np.isfinite(ya))):
        return (math.nan, math.nan)
    if float(np.ptp(xa)) == 0.0 or float(np.ptp(ya)) == 0.0:
        return (math.nan, math.nan)
    harmonics = min(SOBOL_HARMONICS, (n // 2) // 2 - 1)
    rng = np.random.default_rng(seed)
    order = rng.permutation(n)
    problem = {"num_vars": 1, "names": ["x"], "bounds": [[float(xa.min()), float(xa.max())]]}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a degenerate bootstrap draw: its NaN is reported
        si = rbd_fast.analyze(
            problem,
            xa[order, None],
            ya[order],
            M=harmonics,
            num_resamples=SOBOL_RESAMPLES,
            conf_level=CONFIDENCE,
            seed=rng,
        )
    s1, conf = float(si["S1"][0]), float(si["S1_conf"][0])
    return (s1 if math.isfinite(s1) else math.nan, conf if math.isfinite(conf) else math.nan)


def _spearman(x: F64, y: F64) -> tuple[float, float]:
    from scipy.stats import spearmanr

    if x.shape[0] < MIN_ROWS or float(np.ptp(x)) == 0.0 or float(np.ptp(y)) == 0.0:
        return (math.nan, math.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = spearmanr(x, y)
    return (float(r.statistic), float(r.pvalue))


def _finite_pair(x: Any, y: Any) -> tuple[F64, F64]:
    xa = np.asarray(x, dtype=float)
    ya = np.asarray(y, dtype=float)
    ok = np.isfinite(xa) & np.isfinite(ya)
    return xa[ok], ya[ok]


# -- reading the folder -------------------------------------------------------------------------
def _study_dict(meta: Mapping[str, Any]) -> dict[str, Any]:
    """The study-file tables of :meth:`Study.to_dict` (to rebuild the study)."""
    s = meta["study"]
    study = {
        k: s[k]
        for k in ("name", "model", "params", "controllers", "scenarios", "metrics", "criteria")
    }
    for k in ("t_end", "rtol", "linear"):
        if s.get(k) is not None:
            study[k] = s[k]
    sampling = {"method": s["method"], "seed": s["seed"]}
    if s["method"] != "grid":
        sampling["samples"] = s["samples"]
    params = {k: {kk: (list(vv) if isinstance(vv, list | tuple) else vv) for kk, vv in v.items()}
              for k, v in s.get("parameters", {}).items()}  # fmt: skip
    return {"study": study, "sampling": sampling, "parameters": params}


def _load(folder: Path) -> tuple[dict[str, Any], Study | None, str | None, pd.DataFrame]:
    if not folder.is_dir():
        raise StudyReportError(f"study folder {str(folder)!r}: not a directory")
    meta_path = folder / "study.json"
    if not meta_path.is_file():
        raise StudyReportError(
            f"study folder {str(folder)!r}: no study.json (not a folder written by "
            "'drivetrain-ctrl study run')"
        )
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
        s = meta["study"]
        if not isinstance(s, dict):
            raise TypeError("'study' is not a table")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise StudyReportError(f"{meta_path}: cannot read the study ({exc})") from None
    from .runner import read_results

    try:
        table = read_results(folder)
    except FileNotFoundError as exc:
        raise StudyReportError(f"study folder {str(folder)!r}: {exc}") from None
    for col in ("key", "sample", "controller", "scenario", "status", "pass"):
        if col not in table.columns:
            raise StudyReportError(f"{folder / 'results'}: the table has no column {col!r}")
    study: Study | None = None
    why: str | None = None
    try:
        study = Study.from_dict(_study_dict(meta))
        # the same study: every key study.json holds (a folder of an older version lacks some)
        again = json.loads(json.dumps(study.to_dict(), default=str))
        if {k: again.get(k) for k in s} != s:
            study, why = None, "the study rebuilt from study.json differs from it"
    except (StudyError, KeyError, TypeError) as exc:
        why = f"the study in study.json cannot be rebuilt here ({exc})"
    return s, study, why, table


def _criteria(s: Mapping[str, Any], study: Study | None) -> list[Criterion]:
    if study is not None:
        return list(study.criteria)
    return [_parse_criterion(c, f"study.criteria[{i}]") for i, c in enumerate(s["criteria"])]


# -- the parts ----------------------------------------------------------------------------------
def _groups(table: pd.DataFrame) -> list[tuple[str, str, str, NDArray[np.bool_]]]:
    """(label, controller, scenario, row mask) per controller x scenario, in table order."""
    pairs = list(dict.fromkeys(zip(table["controller"], table["scenario"], strict=True)))
    several = len({sc for _, sc in pairs}) > 1
    out = []
    for c, sc in pairs:
        mask = ((table["controller"] == c) & (table["scenario"] == sc)).to_numpy()
        out.append((f"{c} @ {sc}" if several else str(c), str(c), str(sc), mask))
    return out


def _met(table: pd.DataFrame, c: Criterion) -> NDArray[np.bool_]:
    """Criterion ``c`` met by each row: the run finished (status ``ok``) and its metric meets the
    threshold (computed from the metric, not read from the ``pass:`` column)."""
    if c.metric not in table.columns:
        return np.zeros(len(table), dtype=bool)
    ok = (table["status"] == "ok").to_numpy()
    return np.asarray(ok & c.check(table[c.metric].to_numpy(dtype=float)), dtype=bool)


def _rate(k: int, n: int) -> dict[str, Any]:
    lo, hi = wilson_interval(k, n)
    return {"n": n, "passed": k, "rate": k / n if n else None, "ci_low": lo, "ci_high": hi}


def _pass_rates(table: pd.DataFrame, groups: Sequence[Any], criteria: Sequence[Criterion]) -> Any:
    out = []
    for label, c, sc, mask in groups:
        sub = table[mask]
        e = {
            "group": label,
            "controller": c,
            "scenario": sc,
            **_rate(int(sub["pass"].sum()), len(sub)),
        }
        e["criteria"] = {cr.text: _rate(int(_met(sub, cr).sum()), len(sub)) for cr in criteria}
        out.append(e)
    return out


def _metric_columns(
    table: pd.DataFrame, s: Mapping[str, Any], crit: Sequence[Criterion]
) -> list[str]:
    """Numeric metrics of the table: the criteria's first, then the study's order."""
    order = [c.metric for c in crit] + list(s.get("metrics", []))
    return [
        m
        for m in dict.fromkeys(order)
        if m in table.columns and m != "status" and pd.api.types.is_numeric_dtype(table[m])
    ]


def _histograms(table: pd.DataFrame, groups: Sequence[Any], metrics: Sequence[str]) -> Any:
    out = {}
    for m in metrics:
        v = table[m].to_numpy(dtype=float)
        fin = v[np.isfinite(v)]
        entry: dict[str, Any] = {"unit": METRICS[m].unit if m in METRICS else "", "groups": {}}
        if fin.size == 0:
            entry["edges"] = None
        else:
            lo, hi = float(fin.min()), float(fin.max())
            if hi <= lo:
                lo, hi = lo - 0.5 * max(1.0, abs(lo)) * 1e-3, hi + 0.5 * max(1.0, abs(hi)) * 1e-3
            edges = np.linspace(lo, hi, _bins_for(fin.size) + 1)
            entry["edges"] = edges.tolist()
        for label, _, _, mask in groups:
            g = v[mask]
            gf = g[np.isfinite(g)]
            counts = (
                np.histogram(gf, bins=np.asarray(entry["edges"]))[0].tolist()
                if entry["edges"] is not None
                else []
            )
            entry["groups"][label] = {
                "counts": [int(x) for x in counts],
                "n": int(gf.size),
                "undefined": int(g.size - gf.size),
                "min": float(gf.min()) if gf.size else None,
                "median": float(np.median(gf)) if gf.size else None,
                "max": float(gf.max()) if gf.size else None,
            }
        out[m] = entry
    return out


def _sensitivity(
    table: pd.DataFrame,
    groups: Sequence[Any],
    params: Sequence[str],
    metrics: Sequence[str],
    crit: Sequence[Criterion],
) -> Any:
    ranked_on = [c.metric for c in crit if c.metric in metrics] or list(metrics)
    ranked_on = list(dict.fromkeys(ranked_on))
    out = []
    for label, c, sc, mask in groups:
        sub = table[mask]
        per: dict[str, dict[str, Any]] = {}
        for m in metrics:
            per[m] = {}
            for p in params:
                x, y = _finite_pair(sub[PARAM + p], sub[m])
                rho, pv = _spearman(x, y)
                index, half_width = first_order_index(x, y)
                per[m][p] = {
                    "spearman": rho,
                    "p_value": pv,
                    "sobol_first": index,
                    "sobol_first_conf": half_width,
                    "n": int(x.size),
                }
        ranking: list[dict[str, Any]] = []
        for p in params:
            s1 = [(per[m][p]["sobol_first"], m) for m in ranked_on]
            s1 = [(v, m) for v, m in s1 if v is not None and math.isfinite(v)]
            rh = [
                abs(per[m][p]["spearman"])
                for m in ranked_on
                if math.isfinite(per[m][p]["spearman"])
            ]
            best = max(s1, default=(math.nan, None))
            ranking.append(
                {
                    "parameter": p,
                    "sobol_first_max": best[0],
                    "on_metric": best[1],
                    "abs_spearman_max": max(rh, default=math.nan),
                }
            )
        ranking.sort(
            key=lambda r: (
                -(r["sobol_first_max"] if math.isfinite(r["sobol_first_max"]) else -1.0),
                -(r["abs_spearman_max"] if math.isfinite(r["abs_spearman_max"]) else -1.0),
                r["parameter"],
            )
        )
        out.append({"group": label, "controller": c, "scenario": sc, "ranked_on": ranked_on,
                    "metrics": per, "ranking": ranking})  # fmt: skip
    return out


def _violation(c: Criterion, v: float) -> float:
    """How far ``v`` misses criterion ``c``, relative to the threshold (<= 0: met; inf:
    undefined)."""
    if not math.isfinite(v):
        return math.inf
    scale = abs(c.threshold) if c.threshold != 0 else 1.0
    if c.op in ("<=", "<"):
        return (v - c.threshold) / scale
    if c.op in (">=", ">"):
        return (c.threshold - v) / scale
    if c.op == "==":
        return abs(v - c.threshold) / scale
    return 0.0 if v != c.threshold else 1.0


def _scores(table: pd.DataFrame, crit: Sequence[Criterion]) -> F64:
    cols = [c for c in crit if c.metric in table.columns]
    if not cols:
        return np.full(len(table), math.nan)
    vals = np.array([[_violation(c, float(x)) for x in table[c.metric]] for c in cols]).T
    return np.asarray(vals.max(axis=1), dtype=float)


def _trace(run: Any) -> dict[str, Any]:
    """The worst run's traces at :data:`TRACE_RATE_HZ`: engine and driven-plate speed [rpm],
    clutch torque [N m], vehicle acceleration [m/s^2] (the right derivative of the model)."""
    res = run.result
    T = np.asarray(res.t, dtype=float)
    t = np.arange(float(T[0]), float(T[-1]) + 1e-12, 1.0 / TRACE_RATE_HZ)
    model = res.model
    driven = "omega_disc" if run.drivetrain.kind == "full" else "omega_primary"
    clutch = [c.name for c in model.chain.couplings].index("clutch")
    right, _ = state_accelerations(res)
    acc = right[:, model.state_index("v_vehicle")]
    ref = run.scenario.reference
    return {
        "t_s": t.tolist(),
        "omega_engine_rpm": (np.interp(t, T, res.state("omega_engine")) * RAD_S_TO_RPM).tolist(),
        "omega_driven_rpm": (np.interp(t, T, res.state(driven)) * RAD_S_TO_RPM).tolist(),
        "omega_ref_rpm": [float(ref(float(x))) * RAD_S_TO_RPM for x in t]
        if ref is not None
        else None,
        "clutch_torque_Nm": np.interp(t, T, res.coupling_torques()[:, clutch]).tolist(),
        "vehicle_accel_m_s2": np.interp(t, T, acc).tolist(),
        "driven_state": driven,
    }


def _worst(
    table: pd.DataFrame,
    crit: Sequence[Criterion],
    params: Sequence[str],
    study: Study | None,
    why: str | None,
    count: int,
    resimulate: bool,
) -> dict[str, Any]:
    if not crit:
        return {"rows": [], "reason": "the study has no criteria: no run is worse than another"}
    score = _scores(table, crit)
    done = (table["status"] != "failed").to_numpy()
    rows = []
    for c in dict.fromkeys(table["controller"]):
        idx = np.flatnonzero(done & (table["controller"] == c).to_numpy())
        order = sorted(idx, key=lambda i: (-score[i], str(table["key"].iloc[i])))[:count]
        for i in order:
            r = table.iloc[i]
            e: dict[str, Any] = {
                "key": str(r["key"]),
                "controller": str(c),
                "scenario": str(r["scenario"]),
                "sample": int(r["sample"]),
                "status": str(r["status"]),
                "pass": bool(r["pass"]),
                "score": float(score[i]) if math.isfinite(score[i]) else None,
                "params": {p: float(r[PARAM + p]) for p in params},
                "metrics": {
                    k.metric: float(r[k.metric]) for k in crit if k.metric in table.columns
                },
                "missed": [k.text for k in crit if not _met(table.iloc[[int(i)]], k)[0]],
                "trace": None,
                "resimulated": None,
            }
            if not resimulate:
                e["resimulated"] = {"error": "re-simulation switched off (resimulate=False)"}
            elif study is None:
                e["resimulated"] = {"error": f"not re-simulated: {why}"}
            else:
                e["resimulated"] = _resimulate(study, r, params, crit, e)
            rows.append(e)
    return {"rows": rows, "reason": None}


def _resimulate(
    study: Study, r: Any, params: Sequence[str], crit: Sequence[Criterion], e: dict[str, Any]
) -> dict[str, Any]:
    values = {p: float(r[PARAM + p]) for p in params}
    try:
        case = study.case(
            int(r["sample"]),
            values,
            str(r["controller"]),
            study.scenario_names.index(str(r["scenario"])),
        )
        run = simulate_case(case)
    except Exception as exc:  # noqa: BLE001 - reported in the report, the others go on
        return {"error": f"{type(exc).__name__}: {exc}"}
    e["trace"] = _trace(run)
    got = {k.metric: run.metrics.get(k.metric) for k in crit}
    same = True
    for m, v in e["metrics"].items():
        g = got.get(m)
        if g is None:
            same = same and not math.isfinite(v)
        else:
            same = same and math.isclose(float(g), v, rel_tol=1e-6, abs_tol=1e-9)
    return {"error": None, "metrics": got, "reproduces_table": bool(same)}


def _linear(
    table: pd.DataFrame, groups: Sequence[Any], metrics: Sequence[str], crit: Sequence[Criterion]
) -> Any:
    lin = sorted(
        c for c in table.columns if c.startswith(LIN) and pd.api.types.is_numeric_dtype(table[c])
    )
    if not lin:
        return {
            "available": False,
            "columns": [],
            "reason": "the results table has no paired linear figures (no lin: columns; a folder "
            "written before the study runner computed them)",
        }
    outcomes = [m for m in LINEAR_OUTCOMES if m in metrics] or [
        c.metric for c in crit if c.metric in metrics
    ][:2]
    outcomes = [*dict.fromkeys(outcomes), "pass"]
    corr = []
    pooled = [("all runs", None, None, np.ones(len(table), dtype=bool))] if len(groups) > 1 else []
    for label, c, sc, mask in [*groups, *pooled]:
        sub = table[mask]
        ok = (sub["status"] != "failed").to_numpy()
        per: dict[str, dict[str, Any]] = {}
        for col in lin:
            per[col] = {}
            for m in outcomes:
                y = sub[m].astype(float) if m == "pass" else sub[m]
                x, yy = _finite_pair(sub[col][ok], y[ok])
                rho, pv = _spearman(x, yy)
                per[col][m] = {"spearman": rho, "p_value": pv, "n": int(x.size)}
        corr.append({"group": label, "controller": c, "scenario": sc, "correlations": per})
    plotted = [c for c in LINEAR_PLOTTED if c in lin] or lin[: len(LINEAR_PLOTTED)]
    return {
        "available": True,
        "columns": lin,
        "plotted": plotted,
        "outcomes": outcomes,
        "groups": corr,
        "reason": None,
    }


#: a number in a message (not the digits of a name such as k12_max)
_NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _reason(status: str, error: Any) -> str:
    text = "" if error is None or (isinstance(error, float) and math.isnan(error)) else str(error)
    text = _NUMBER.sub("#", text.strip())
    return f"{status}: {text}" if text else status


def _failures(table: pd.DataFrame, groups: Sequence[Any], crit: Sequence[Criterion]) -> Any:
    bad = table[table["status"] != "ok"]
    reasons: dict[str, dict[str, Any]] = {}
    for _, r in bad.iterrows():
        k = _reason(str(r["status"]), r["error"])
        e = reasons.setdefault(k, {"reason": k, "count": 0, "by_group": {}, "example_key": str(r["key"]),
                                   "example_error": None if pd.isna(r["error"]) else str(r["error"])})  # fmt: skip
        e["count"] += 1
        g = next(label for label, _, _, mask in groups if mask[table.index.get_loc(r.name)])
        e["by_group"][g] = e["by_group"].get(g, 0) + 1
    runs = sorted(reasons.values(), key=lambda e: (-e["count"], e["reason"]))
    missed = []
    for label, _, _, mask in groups:
        sub = table[mask]
        missed.append(
            {
                "group": label,
                "runs": len(sub),
                "not_finished": int((sub["status"] != "ok").sum()),
                "criteria": {c.text: int((~_met(sub, c)).sum()) for c in crit},
            }
        )
    status = {str(k): int(v) for k, v in sorted(table["status"].value_counts().items())}
    return {"status_counts": status, "runs": runs, "criteria": missed}


def _points(
    table: pd.DataFrame, groups: Sequence[Any], params: Sequence[str], metrics: Sequence[str]
) -> Any:
    label = np.empty(len(table), dtype=object)
    for lab, _, _, mask in groups:
        label[mask] = lab
    lin = sorted(
        c for c in table.columns if c.startswith(LIN) and pd.api.types.is_numeric_dtype(table[c])
    )
    return {
        "key": table["key"].astype(str).tolist(),
        "group": [str(x) for x in label],
        "status": table["status"].astype(str).tolist(),
        "pass": [bool(x) for x in table["pass"]],
        "params": {p: table[PARAM + p].astype(float).tolist() for p in params},
        "metrics": {m: table[m].astype(float).tolist() for m in metrics},
        "lin": {c: table[c].astype(float).tolist() for c in lin},
    }


# -- the whole ----------------------------------------------------------------------------------
def analyse_study(folder: str | Path, *, worst: int = 2, resimulate: bool = True) -> StudyAnalysis:
    """Analyse study folder ``folder`` (written by :func:`~drivetrain_ctrl.studies.runner.run_study`).

    ``worst``: runs per controller re-simulated and kept as traces (0: none);
    ``resimulate``: False keeps the worst runs' table values without running them again.
    Raises :class:`StudyReportError` naming the folder for a missing folder, ``study.json`` or
    results table. Returns a :class:`StudyAnalysis` (its ``data``: see the module docstring).
    """
    if isinstance(folder, bool) or not isinstance(folder, str | Path) or not str(folder).strip():
        raise StudyReportError(
            f"folder = {folder!r}: give a study folder (DIR of 'study run --out DIR')"
        )
    if isinstance(worst, bool) or not isinstance(worst, int) or worst < 0:
        raise StudyReportError(f"worst = {worst!r}: must be an integer >= 0")
    if not isinstance(resimulate, bool):
        raise StudyReportError(f"resimulate = {resimulate!r}: must be True or False")
    path = Path(folder)
    s, study, why, table = _load(path)
    crit = _criteria(s, study)
    params = [c.removeprefix(PARAM) for c in table.columns if c.startswith(PARAM)]
    metrics = _metric_columns(table, s, crit)
    groups = _groups(table)
    data = {
        "study": {
            k: s.get(k)
            for k in (
                "name",
                "model",
                "params",
                "controllers",
                "scenarios",
                "method",
                "samples",
                "seed",
                "metrics",
                "criteria",
                "t_end",
                "rtol",
                "parameters",
            )
        },  # fmt: skip
        "digest": None,
        "rows": {
            "total": len(table),
            "expected": int(s.get("samples", 0))
            * len(s.get("controllers", []))
            * len(s.get("scenarios", [])),
            "ok": int((table["status"] == "ok").sum()),
            "failed": int((table["status"] == "failed").sum()),
            "passed": int(table["pass"].sum()),
        },
        "groups": [g[0] for g in groups],
        "parameters": params,
        "metrics": metrics,
        "metric_units": {m: METRICS[m].unit if m in METRICS else "" for m in metrics},
        "confidence": CONFIDENCE,
        "methods": {
            "interval": "Wilson score interval (scipy.stats.binomtest(...).proportion_ci(method='wilson'))",
            "rank_correlation": "Spearman (scipy.stats.spearmanr), runs with a defined value",
            "sobol": "first-order index from given data: RBD-FAST (SALib.analyze.rbd_fast, "
            "Plischke 2010 ordering, Tissot-Prieur 2012 bias correction), confidence half-width "
            "from SALib's bootstrap of half the runs",
            "sobol_harmonics": SOBOL_HARMONICS,
            "sobol_resamples": SOBOL_RESAMPLES,
            "sobol_seed": SOBOL_SEED,
            "min_rows": MIN_ROWS,
        },
        "pass_rates": _pass_rates(table, groups, crit),
        "histograms": _histograms(table, groups, metrics),
        "sensitivity": _sensitivity(table, groups, params, metrics, crit),
        "worst": _worst(table, crit, params, study, why, worst, resimulate),
        "linear": _linear(table, groups, metrics, crit),
        "failures": _failures(table, groups, crit),
        "points": _points(table, groups, params, metrics),
    }
    try:
        data["digest"] = json.loads((path / "study.json").read_text(encoding="utf-8")).get("digest")
    except (OSError, ValueError):
        data["digest"] = None
    return StudyAnalysis(folder=path, data=dict(json_ready(data)), table=table)
