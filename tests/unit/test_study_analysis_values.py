"""Value tests of drivetrain_ctrl.studies.analysis (issue 22 item 4): every number of a study
report's data recomputed here, plainly, from the made-up records the synthetic folder was
written from: row counts, pass rates and their Wilson intervals (scipy's binomtest), shared
histogram edges and counts (numpy), rank correlations (scipy's spearmanr), first-order indices
(SALib's rbd_fast called directly), the ranking, the worst runs and their violations, the paired
linear figures' correlations, failure reasons and the points; and each bad folder or argument
named (``./dev mutate drivetrain_ctrl/studies/analysis.py``).

The folders are written with the runner's own writers (``_prepare_folder``, ``_row``,
``_write_chunk``), as ``tests/integration/test_study_report.py`` does; nothing is simulated."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from drivetrain_ctrl.sim.metrics import METRICS
from drivetrain_ctrl.studies.analysis import (
    StudyReportError,
    _violation,
    analyse_study,
    first_order_index,
)
from drivetrain_ctrl.studies.case import LINEAR_FIGURES
from drivetrain_ctrl.studies.runner import _prepare_folder, _row, _schema, _write_chunk
from drivetrain_ctrl.studies.study import Criterion, Study

N = 24  # samples
CRIT = ["lockup_time_s <= 2.5", "jerk_max_m_s3 <= 20", "engine_speed_min_rpm >= 700"]
METR = ["lockup_time_s", "jerk_max_m_s3", "engine_speed_min_rpm", "n_lock_events"]


def _definition(scenarios: list[str], linear: bool) -> dict[str, Any]:
    return {
        "study": {
            "name": "values",
            "model": "reduced",
            "controllers": ["paper", "pi"],
            "scenarios": scenarios,
            "metrics": METR,
            "criteria": CRIT,
            "linear": linear,
        },
        "sampling": {"method": "lhs", "samples": N, "seed": 5},
        "parameters": {
            "vehicle.M_v": {"dist": "uniform", "low": 1100.0, "high": 1500.0},
            "clutch.k12_max": {"dist": "uniform", "low": 200.0, "high": 300.0},
        },
    }


def _record(i: int, c: str, sc: str, m: float, k: float) -> dict[str, Any]:
    """Made-up figures: lock-up time grows with the mass, jerk falls with the capacity; two
    kinds of failure (numbers in their messages), one undefined lock-up time, a constant
    count, one undefined judder margin."""
    if i % 7 == 3:
        return {"status": "failed", "error": f"ZenoError: Zeno at t = {1 + i / 100:.2f} s"}
    if i % 11 == 5 and c == "pi":
        return {"status": "failed", "error": f"invalid input: vehicle.M_v = {-m:.1f}: must be > 0"}
    if i == 8 and c == "paper":
        return {"status": "max_steps", "error": None, "lockup_time_s": 9.0}
    hill = 0.3 if sc == "hill-start" else 0.0
    return {
        "status": "ok",
        "lockup_time_s": None if (i == 12 and c == "paper") else 2.0 + (m - 1100.0) / 500.0 + hill,
        "jerk_max_m_s3": 12.0 + (300.0 - k) / (10.0 if c == "paper" else 5.0),
        "engine_speed_min_rpm": 760.0 - 2.0 * i,
        "n_lock_events": 1.0,
        "lin:Ms": 1.2 + k / 200.0,
        "lin:gain_margin": 3.0 + 0.01 * ((i * 7) % 5),
        "lin:judder_margin": None if i == 2 else 2.0 - i / 100.0,
    }


def _write(out: Path, scenarios: list[str], *, linear: bool = True) -> Path:
    study = Study.from_dict(_definition(scenarios, linear))
    samples = _prepare_folder(study, out)
    rows = []
    for i in range(study.samples):
        vals = {k: float(v) for k, v in samples.iloc[i].items()}
        for c in study.controller_names:
            for j, sc in enumerate(study.scenario_names):
                rec = _record(i, c, sc, vals["vehicle.M_v"], vals["clutch.k12_max"])
                item = (study.case(i, vals, c, j).label, i, c, sc, vals)
                rows.append(_row(item, rec, study.metrics, study.criteria, linear))
    _write_chunk(out / "results", rows[::2], _schema(study))
    _write_chunk(out / "results", rows[1::2], _schema(study))
    return out


@pytest.fixture(scope="module")
def one(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _write(tmp_path_factory.mktemp("one") / "s", ["paper-start"])


@pytest.fixture(scope="module")
def two(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _write(tmp_path_factory.mktemp("two") / "s", ["paper-start", "hill-start"])


@pytest.fixture(scope="module")
def one_data(one: Path) -> dict[str, Any]:
    return analyse_study(one, resimulate=False).data


@pytest.fixture(scope="module")
def two_data(two: Path) -> dict[str, Any]:
    return analyse_study(two, worst=3, resimulate=False).data


def _records(scenarios: list[str]) -> pd.DataFrame:
    """The made-up records, one per row, in key order, with the parameters (plain pandas)."""
    study = Study.from_dict(_definition(scenarios, True))
    from drivetrain_ctrl.studies.study import sample_table

    samples = sample_table(study)
    out = []
    for i in range(N):
        m, k = float(samples["vehicle.M_v"][i]), float(samples["clutch.k12_max"][i])
        for c in ("paper", "pi"):
            for sc in scenarios:
                rec = _record(i, c, sc, m, k)
                key = f"s{i:06d}|{c}|{sc}"
                row = {"key": key, "sample": i, "controller": c, "scenario": sc, "M": m, "k": k}
                row["status"] = rec["status"]
                row["error"] = rec.get("error")
                for name in [*METR, *LINEAR_FIGURES]:
                    v = rec.get(name)
                    row[name] = math.nan if v is None else float(v)
                out.append(row)
    df = pd.DataFrame(out).sort_values("key").reset_index(drop=True)
    ok = df["status"] == "ok"
    with np.errstate(invalid="ignore"):
        df["c0"] = ok & (df["lockup_time_s"] <= 2.5)
        df["c1"] = ok & (df["jerk_max_m_s3"] <= 20.0)
        df["c2"] = ok & (df["engine_speed_min_rpm"] >= 700.0)
    df["pass"] = df["c0"] & df["c1"] & df["c2"]
    return df


def _wilson(k: int, n: int) -> tuple[float, float]:
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)


# -- rows, groups, pass rates -------------------------------------------------------------------


def test_row_counts_groups_and_study_block(one_data: dict[str, Any], one: Path) -> None:
    df = _records(["paper-start"])
    r = one_data["rows"]
    assert r == {
        "total": 2 * N,
        "expected": 2 * N,
        "ok": int((df["status"] == "ok").sum()),
        "failed": int((df["status"] == "failed").sum()),
        "passed": int(df["pass"].sum()),
    }
    assert 0 < r["passed"] < r["ok"] < r["total"] and r["failed"] > 0
    assert one_data["groups"] == ["paper", "pi"]  # one scenario: the controller's name
    assert one_data["parameters"] == ["vehicle.M_v", "clutch.k12_max"]
    # the criteria's metrics first, then the study's order; numeric only
    assert one_data["metrics"] == [
        "lockup_time_s",
        "jerk_max_m_s3",
        "engine_speed_min_rpm",
        "n_lock_events",
    ]
    assert one_data["metric_units"] == {m: METRICS[m].unit for m in one_data["metrics"]}
    assert one_data["metric_units"]["lockup_time_s"] == "s"
    assert one_data["study"]["criteria"] == CRIT and one_data["study"]["samples"] == N
    assert one_data["digest"] == json.loads((one / "study.json").read_text())["digest"]
    assert one_data["digest"] == Study.from_dict(_definition(["paper-start"], True)).digest
    m = one_data["methods"]
    assert (m["sobol_seed"], m["min_rows"], m["sobol_harmonics"], m["sobol_resamples"]) == (
        23,
        10,
        10,
        100,
    )
    assert one_data["confidence"] == 0.95


def test_groups_of_several_scenarios_are_labelled_controller_at_scenario(
    two_data: dict[str, Any],
) -> None:
    assert two_data["groups"] == [
        "paper @ hill-start",
        "paper @ paper-start",
        "pi @ hill-start",
        "pi @ paper-start",
    ]  # table (key) order
    assert two_data["rows"]["total"] == two_data["rows"]["expected"] == 4 * N


def test_pass_rates_and_wilson_intervals(two_data: dict[str, Any]) -> None:
    df = _records(["paper-start", "hill-start"])
    for e in two_data["pass_rates"]:
        sub = df[(df["controller"] == e["controller"]) & (df["scenario"] == e["scenario"])]
        n, k = len(sub), int(sub["pass"].sum())
        assert e["group"] == f"{e['controller']} @ {e['scenario']}"
        assert (e["n"], e["passed"]) == (n, k) and e["rate"] == pytest.approx(k / n)
        assert (e["ci_low"], e["ci_high"]) == pytest.approx(_wilson(k, n), rel=1e-8)
        assert list(e["criteria"]) == ["lockup_time_s <= 2.5", "jerk_max_m_s3 <= 20",
                                       "engine_speed_min_rpm >= 700"]  # fmt: skip
        for col, (text, got) in zip(("c0", "c1", "c2"), e["criteria"].items(), strict=True):
            kk = int(sub[col].sum())
            assert (got["n"], got["passed"]) == (n, kk), text
            assert got["rate"] == pytest.approx(kk / n)
            assert (got["ci_low"], got["ci_high"]) == pytest.approx(_wilson(kk, n), rel=1e-8)
    # the hill start locks up 0.3 s later: fewer runs meet the lock-up criterion there
    rates = {e["group"]: e["criteria"]["lockup_time_s <= 2.5"]["passed"] for e in two_data["pass_rates"]}  # fmt: skip
    assert rates["paper @ hill-start"] < rates["paper @ paper-start"]


# -- histograms ----------------------------------------------------------------------------------


def test_histograms_share_edges_and_count_defined_values(two_data: dict[str, Any]) -> None:
    df = _records(["paper-start", "hill-start"])
    for m in ("lockup_time_s", "jerk_max_m_s3", "engine_speed_min_rpm"):
        h = two_data["histograms"][m]
        v = df[m].to_numpy()
        fin = v[np.isfinite(v)]
        bins = int(min(50, max(2, round(math.sqrt(fin.size)))))
        edges = np.linspace(fin.min(), fin.max(), bins + 1)
        assert h["edges"] == pytest.approx(edges.tolist(), rel=1e-8)
        assert h["unit"] == METRICS[m].unit
        for label, g in h["groups"].items():
            c, sc = label.split(" @ ")
            gv = df[(df["controller"] == c) & (df["scenario"] == sc)][m].to_numpy()
            gf = gv[np.isfinite(gv)]
            assert g["counts"] == np.histogram(gf, bins=edges)[0].tolist()
            assert sum(g["counts"]) == g["n"] == gf.size
            assert g["undefined"] == gv.size - gf.size
            assert (g["min"], g["median"], g["max"]) == pytest.approx(
                (gf.min(), np.median(gf), gf.max())
            )
    # failed runs and the one undefined lock-up time are left out and counted (the max_steps
    # row keeps its value)
    g = two_data["histograms"]["lockup_time_s"]["groups"]["paper @ paper-start"]
    assert g["undefined"] == sum(1 for i in range(N) if i % 7 == 3) + 1


def test_a_constant_metric_gets_a_narrow_bin_around_its_value(one_data: dict[str, Any]) -> None:
    h = one_data["histograms"]["n_lock_events"]
    # all values 1.0: the edges span 1 -+ 0.5e-3 max(1, |1|)
    assert h["edges"][0] == pytest.approx(1.0 - 0.5e-3, rel=1e-8)
    assert h["edges"][-1] == pytest.approx(1.0 + 0.5e-3, rel=1e-8)
    ok = sum(1 for i in range(N) if i % 7 != 3 and i != 8)
    assert sum(h["groups"]["paper"]["counts"]) == ok


def test_a_histogram_of_a_metric_without_values_has_no_edges(tmp_path: Path) -> None:
    out = _write(tmp_path / "s", ["paper-start"], linear=False)
    df = pd.read_parquet(out / "results")
    df["n_lock_events"] = math.nan
    # rewrite the table with the column undefined everywhere
    for f in (out / "results").glob("chunk-*.parquet"):
        f.unlink()
    df.to_parquet(out / "results" / "chunk-0.parquet")
    h = analyse_study(out, resimulate=False).data["histograms"]["n_lock_events"]
    assert h["edges"] is None
    assert h["groups"]["paper"] == {"counts": [], "n": 0, "undefined": N, "min": None,
                                    "median": None, "max": None}  # fmt: skip


# -- sensitivity ---------------------------------------------------------------------------------


def _rbd_fast(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """SALib's RBD-FAST called directly, with the documented seeded row order and harmonics."""
    from SALib.analyze import rbd_fast

    n = x.size
    rng = np.random.default_rng(23)
    order = rng.permutation(n)
    problem = {"num_vars": 1, "names": ["x"], "bounds": [[float(x.min()), float(x.max())]]}
    si = rbd_fast.analyze(problem, x[order, None], y[order], M=min(10, n // 4 - 1),
                          num_resamples=100, conf_level=0.95, seed=rng)  # fmt: skip
    return float(si["S1"][0]), float(si["S1_conf"][0])


def test_rank_correlations_and_first_order_indices(one_data: dict[str, Any]) -> None:
    df = _records(["paper-start"])
    for e in one_data["sensitivity"]:
        sub = df[df["controller"] == e["controller"]]
        assert e["group"] == e["controller"] and e["scenario"] == "paper-start"
        assert e["ranked_on"] == ["lockup_time_s", "jerk_max_m_s3", "engine_speed_min_rpm"]
        for m in ("lockup_time_s", "jerk_max_m_s3", "engine_speed_min_rpm"):
            for p, col in (("vehicle.M_v", "M"), ("clutch.k12_max", "k")):
                x, y = sub[col].to_numpy(), sub[m].to_numpy()
                ok = np.isfinite(x) & np.isfinite(y)
                got = e["metrics"][m][p]
                r = stats.spearmanr(x[ok], y[ok])
                assert got["n"] == int(ok.sum())
                assert got["spearman"] == pytest.approx(r.statistic, rel=1e-8)
                assert got["p_value"] == pytest.approx(r.pvalue, rel=1e-8)
                s1, conf = _rbd_fast(x[ok], y[ok])
                assert got["sobol_first"] == pytest.approx(s1, rel=1e-8)
                assert got["sobol_first_conf"] == pytest.approx(conf, rel=1e-8)
        # the jerk is the capacity alone (rank correlation -1; the lock-up time too, but for
        # paper's max_steps run that kept a lock-up time)
        if e["controller"] == "pi":
            assert e["metrics"]["lockup_time_s"]["vehicle.M_v"]["spearman"] == pytest.approx(1.0)
        assert e["metrics"]["jerk_max_m_s3"]["clutch.k12_max"]["spearman"] == pytest.approx(-1.0)
        # a constant metric: undefined correlation and index
        c = e["metrics"]["n_lock_events"]["vehicle.M_v"]
        assert c["spearman"] is None and c["sobol_first"] is None


def test_the_ranking_puts_the_largest_index_first(one_data: dict[str, Any]) -> None:
    for e in one_data["sensitivity"]:
        per = e["metrics"]
        want = []
        for p in ("vehicle.M_v", "clutch.k12_max"):
            s1 = [(per[m][p]["sobol_first"], m) for m in e["ranked_on"]]
            best = max((t for t in s1 if math.isfinite(t[0])), key=lambda t: t[0])
            rho = max(abs(per[m][p]["spearman"]) for m in e["ranked_on"])
            want.append({"parameter": p, "sobol_first_max": best[0], "on_metric": best[1],
                         "abs_spearman_max": rho})  # fmt: skip
        want.sort(key=lambda r: -r["sobol_first_max"])
        assert e["ranking"] == want
        assert {r["parameter"]: r["on_metric"] for r in e["ranking"]} == {
            "vehicle.M_v": "lockup_time_s",
            "clutch.k12_max": "jerk_max_m_s3",
        }


def test_fewest_rows_for_a_correlation_and_an_index_is_ten() -> None:
    from drivetrain_ctrl.studies import analysis as A

    x = np.arange(10.0)
    y = x**2
    assert A._spearman(x, y) == pytest.approx((1.0, 0.0), abs=1e-12)
    assert math.isfinite(first_order_index(x, y)[0])
    # a range of exactly 1 in either column is a range like any other
    u = np.linspace(0.0, 1.0, 10)
    for a, b in ((u, y), (x, u), (u, u**2)):
        assert np.ptp(a) == 1.0 or np.ptp(b) == 1.0
        rho, p = A._spearman(a, b)
        assert rho == pytest.approx(stats.spearmanr(a, b).statistic) and math.isfinite(p)
        assert math.isfinite(first_order_index(a, b)[0])
    for a, b in ((x[:9], y[:9]), (np.ones(10), y), (x, np.ones(10))):
        assert all(math.isnan(v) for v in A._spearman(a, b))
        assert all(math.isnan(v) for v in first_order_index(a, b))


# -- worst runs ----------------------------------------------------------------------------------


def _plain_violation(op: str, thr: float, v: float) -> float:
    if not math.isfinite(v):
        return math.inf
    return (v - thr) / abs(thr) if op == "<=" else (thr - v) / abs(thr)


def test_the_worst_runs_are_those_that_miss_their_criteria_most(two_data: dict[str, Any]) -> None:
    df = _records(["paper-start", "hill-start"])
    crit = [("lockup_time_s", "<=", 2.5), ("jerk_max_m_s3", "<=", 20.0),
            ("engine_speed_min_rpm", ">=", 700.0)]  # fmt: skip
    score = np.array(
        [
            max(_plain_violation(op, thr, float(r[m])) for m, op, thr in crit)
            for _, r in df.iterrows()
        ]  # fmt: skip
    )
    rows = two_data["worst"]["rows"]
    assert two_data["worst"]["reason"] is None
    for c in ("paper", "pi"):
        idx = [
            i for i in range(len(df)) if df["controller"][i] == c and df["status"][i] != "failed"
        ]
        idx.sort(key=lambda i: (-score[i], df["key"][i]))
        got = [r for r in rows if r["controller"] == c]
        assert [r["key"] for r in got] == [df["key"][i] for i in idx[:3]]
        for r, i in zip(got, idx[:3], strict=True):
            s = score[i]
            assert r["score"] == (pytest.approx(s) if math.isfinite(s) else None)
            assert r["sample"] == df["sample"][i] and r["scenario"] == df["scenario"][i]
            assert r["status"] == df["status"][i] and r["pass"] == bool(df["pass"][i])
            assert r["params"] == {"vehicle.M_v": pytest.approx(df["M"][i]),
                                   "clutch.k12_max": pytest.approx(df["k"][i])}  # fmt: skip
            for m, _, _ in crit:
                want = df[m][i]
                assert r["metrics"][m] == (pytest.approx(want) if math.isfinite(want) else None)
            missed = [t for t, cc in zip(CRIT, ("c0", "c1", "c2"), strict=True) if not df[cc][i]]
            assert r["missed"] == missed
            assert r["trace"] is None
            assert r["resimulated"] == {"error": "re-simulation switched off (resimulate=False)"}
    # an undefined metric is the worst: paper's max_steps run (no jerk), then the undefined
    # lock-up time, in key order
    assert [r["key"] for r in rows[:2]] == ["s000008|paper|hill-start", "s000008|paper|paper-start"]
    assert rows[0]["score"] is None and rows[2]["key"] == "s000012|paper|hill-start"


def test_no_criteria_no_worst_runs(tmp_path: Path) -> None:
    d = _definition(["paper-start"], False)
    out = tmp_path / "s"
    study = Study.from_dict({**d, "study": {**d["study"], "criteria": []}})
    samples = _prepare_folder(study, out)
    rows = []
    for i in range(study.samples):
        vals = {k: float(v) for k, v in samples.iloc[i].items()}
        rec = _record(i, "paper", "paper-start", vals["vehicle.M_v"], vals["clutch.k12_max"])
        item = (study.case(i, vals, "paper", 0).label, i, "paper", "paper-start", vals)
        rows.append(_row(item, rec, study.metrics, study.criteria, False))
    _write_chunk(out / "results", rows, _schema(study))
    data = analyse_study(out, resimulate=False).data
    assert data["worst"] == {
        "rows": [],
        "reason": "the study has no criteria: no run is worse than another",
    }
    # no criteria: the sensitivity is ranked on every metric
    assert data["sensitivity"][0]["ranked_on"] == METR
    assert data["pass_rates"][0]["criteria"] == {}


@pytest.mark.parametrize(
    ("op", "thr", "v", "want"),
    [
        ("<=", 2.0, 2.5, 0.25),
        ("<", 2.0, 1.0, -0.5),
        (">=", 700.0, 630.0, 0.1),
        (">", 700.0, 770.0, -0.1),
        ("==", 4.0, 5.0, 0.25),
        ("==", 4.0, 3.0, 0.25),
        ("!=", 4.0, 4.0, 1.0),
        ("!=", 4.0, 3.0, 0.0),
        ("<=", 0.0, 3.0, 3.0),  # a zero threshold: absolute
        (">=", -2.0, -3.0, 0.5),  # relative to |threshold|
    ],
)
def test_violation_of_every_operator(op: str, thr: float, v: float, want: float) -> None:
    assert _violation(Criterion("lockup_time_s", op, thr), v) == pytest.approx(want)


# -- linear versus nonlinear ----------------------------------------------------------------------


def test_linear_figures_are_correlated_with_the_outcomes(two_data: dict[str, Any]) -> None:
    df = _records(["paper-start", "hill-start"])
    lin = two_data["linear"]
    assert lin["available"] is True and lin["reason"] is None
    assert lin["columns"] == sorted(LINEAR_FIGURES)
    assert lin["plotted"] == ["lin:Ms", "lin:disk_margin", "lin:gain_margin",
                              "lin:phase_margin_deg", "lin:judder_margin"]  # fmt: skip
    assert lin["outcomes"] == ["lockup_time_s", "jerk_max_m_s3", "pass"]
    assert [g["group"] for g in lin["groups"]] == [*two_data["groups"], "all runs"]
    for g in lin["groups"]:
        if g["group"] == "all runs":
            sub = df
            assert g["controller"] is None and g["scenario"] is None
        else:
            sub = df[(df["controller"] == g["controller"]) & (df["scenario"] == g["scenario"])]
        sub = sub[sub["status"] != "failed"]
        for col in ("lin:Ms", "lin:judder_margin", "lin:gain_margin"):
            for m in ("lockup_time_s", "jerk_max_m_s3", "pass"):
                x = sub[col].to_numpy()
                y = sub[m].to_numpy(dtype=float)
                ok = np.isfinite(x) & np.isfinite(y)
                got = g["correlations"][col][m]
                assert got["n"] == int(ok.sum())
                r = stats.spearmanr(x[ok], y[ok])
                if np.ptp(y[ok]) == 0:  # e.g. every finished run passes: undefined
                    assert got["spearman"] is None and got["p_value"] is None
                    continue
                assert got["spearman"] == pytest.approx(r.statistic, rel=1e-8)
                assert got["p_value"] == pytest.approx(r.pvalue, rel=1e-8)
        # a figure without values: n = 0, undefined correlation
        e = g["correlations"]["lin:disk_margin"]["pass"]
        assert e["n"] == 0 and e["spearman"] is None
    # Ms rises with the capacity, the jerk falls with it
    one = lin["groups"][0]["correlations"]["lin:Ms"]["jerk_max_m_s3"]["spearman"]
    assert one == pytest.approx(-1.0)


def test_one_group_has_no_pooled_row_and_without_lin_columns_says_so(
    one_data: dict[str, Any], tmp_path: Path
) -> None:
    # two groups: each and the pooled runs
    assert [g["group"] for g in one_data["linear"]["groups"]] == ["paper", "pi", "all runs"]
    out = _write(tmp_path / "s", ["paper-start"], linear=False)
    lin = analyse_study(out, resimulate=False).data["linear"]
    assert lin["available"] is False and lin["columns"] == []
    assert "no paired linear figures" in lin["reason"]


def test_the_outcomes_fall_back_to_the_criteria_metrics(tmp_path: Path) -> None:
    d = _definition(["paper-start"], True)
    d["study"]["metrics"] = ["engine_speed_min_rpm", "n_lock_events"]
    d["study"]["criteria"] = ["engine_speed_min_rpm >= 700", "n_lock_events <= 1"]
    out = tmp_path / "s"
    study = Study.from_dict(d)
    samples = _prepare_folder(study, out)
    rows = []
    for i in range(study.samples):
        vals = {k: float(v) for k, v in samples.iloc[i].items()}
        for c in study.controller_names:
            rec = _record(i, c, "paper-start", vals["vehicle.M_v"], vals["clutch.k12_max"])
            rows.append(_row((study.case(i, vals, c, 0).label, i, c, "paper-start", vals), rec,
                             study.metrics, study.criteria, True))  # fmt: skip
    _write_chunk(out / "results", rows, _schema(study))
    data = analyse_study(out, resimulate=False).data
    assert data["linear"]["outcomes"] == ["engine_speed_min_rpm", "n_lock_events", "pass"]


# -- failures and points --------------------------------------------------------------------------


def test_failures_are_counted_by_reason_with_numbers_folded(two_data: dict[str, Any]) -> None:
    df = _records(["paper-start", "hill-start"])
    f = two_data["failures"]
    assert f["status_counts"] == {s: int(n) for s, n in sorted(df["status"].value_counts().items())}  # fmt: skip
    zeno = df[df["error"].fillna("").str.startswith("ZenoError")]
    inval = df[df["error"].fillna("").str.startswith("invalid")]
    steps = df[df["status"] == "max_steps"]
    want = [
        ("failed: ZenoError: Zeno at t = # s", zeno),
        ("failed: invalid input: vehicle.M_v = #: must be > #", inval),
        ("max_steps", steps),
    ]
    want.sort(key=lambda t: (-len(t[1]), t[0]))
    assert [(r["reason"], r["count"]) for r in f["runs"]] == [(w, len(s)) for w, s in want]
    assert len(zeno) > len(inval) > len(steps) > 0
    for r, (_, s) in zip(f["runs"], want, strict=True):
        assert r["example_key"] == s["key"].iloc[0]
        e = s["error"].iloc[0]
        assert r["example_error"] == (None if pd.isna(e) else e)
        by = s.groupby(["controller", "scenario"]).size()
        assert r["by_group"] == {f"{c} @ {sc}": int(n) for (c, sc), n in by.items()}
    for e in f["criteria"]:
        c, sc = e["group"].split(" @ ")
        sub = df[(df["controller"] == c) & (df["scenario"] == sc)]
        assert e["runs"] == len(sub)
        assert e["not_finished"] == int((sub["status"] != "ok").sum())
        assert e["criteria"] == {
            t: int((~sub[cc]).sum()) for t, cc in zip(CRIT, ("c0", "c1", "c2"), strict=True)
        }


def test_points_hold_every_row(two_data: dict[str, Any]) -> None:
    df = _records(["paper-start", "hill-start"])
    p = two_data["points"]
    assert p["key"] == df["key"].tolist()
    assert p["group"] == [f"{c} @ {s}" for c, s in zip(df["controller"], df["scenario"], strict=True)]  # fmt: skip
    assert p["status"] == df["status"].tolist() and p["pass"] == df["pass"].tolist()
    assert p["params"]["vehicle.M_v"] == pytest.approx(df["M"].tolist())
    assert p["params"]["clutch.k12_max"] == pytest.approx(df["k"].tolist())
    assert list(p["metrics"]) == two_data["metrics"]
    got = np.array(p["metrics"]["lockup_time_s"], dtype=float)
    assert np.allclose(got, df["lockup_time_s"].to_numpy(), rtol=1e-8, atol=0, equal_nan=True)
    assert np.isnan(got).sum() == df["lockup_time_s"].isna().sum() > 0
    assert sorted(p["lin"]) == sorted(LINEAR_FIGURES)
    got = np.array(p["lin"]["lin:Ms"], dtype=float)
    assert np.allclose(got, df["lin:Ms"].to_numpy(), rtol=1e-8, atol=0, equal_nan=True)


# -- bad folders and arguments --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kw", "named"),
    [
        ({"folder": True}, "folder = True"),
        ({"folder": 3}, "folder = 3"),
        ({"folder": "  "}, "folder = '  '"),
        ({"worst": -1}, "worst = -1: must be an integer >= 0"),
        ({"worst": True}, "worst = True"),
        ({"worst": 1.0}, "worst = 1.0"),
        ({"resimulate": 1}, "resimulate = 1: must be True or False"),
    ],
)
def test_bad_arguments_are_named(one: Path, kw: dict[str, Any], named: str) -> None:
    args: dict[str, Any] = {"folder": one, **kw}
    with pytest.raises(StudyReportError) as e:
        analyse_study(**args)
    assert named in str(e.value)


def test_worst_zero_keeps_no_rows(one: Path) -> None:
    data = analyse_study(one, worst=0, resimulate=False).data
    assert data["worst"] == {"rows": [], "reason": None}


def test_bad_folders_are_named(one: Path, tmp_path: Path) -> None:
    def err(folder: Path) -> str:
        with pytest.raises(StudyReportError) as e:
            analyse_study(folder, resimulate=False)
        return str(e.value)

    assert "not a directory" in err(tmp_path / "missing")
    assert "no study.json" in err(tmp_path)
    bad = tmp_path / "bad"
    shutil.copytree(one, bad)
    (bad / "study.json").write_text("{not json")
    assert "cannot read the study" in err(bad)
    (bad / "study.json").write_text(json.dumps({"study": [1]}))
    assert "cannot read the study ('study' is not a table)" in err(bad)
    (bad / "study.json").write_text(json.dumps({"digest": "x"}))
    assert "cannot read the study" in err(bad)
    empty = tmp_path / "empty"
    shutil.copytree(one, empty)
    for f in (empty / "results").glob("chunk-*.parquet"):
        f.unlink()
    assert "no results" in err(empty)
    nocol = tmp_path / "nocol"
    shutil.copytree(one, nocol)
    df = pd.read_parquet(nocol / "results").drop(columns=["scenario"])
    for f in (nocol / "results").glob("chunk-*.parquet"):
        f.unlink()
    df.to_parquet(nocol / "results" / "chunk-0.parquet")
    assert "the table has no column 'scenario'" in err(nocol)


def test_a_study_that_cannot_be_rebuilt_is_analysed_from_its_table(
    one: Path, tmp_path: Path
) -> None:
    other = tmp_path / "other"
    shutil.copytree(one, other)
    meta = json.loads((other / "study.json").read_text())
    meta["study"]["controllers"] = ["paper", "no-such-controller"]
    (other / "study.json").write_text(json.dumps(meta))
    data = analyse_study(other, worst=1, resimulate=True).data
    for r in data["worst"]["rows"]:
        assert r["resimulated"]["error"].startswith(
            "not re-simulated: the study in study.json cannot be rebuilt here"
        )
    # the criteria come from study.json then
    assert [e["criteria"] for e in data["failures"]["criteria"]][0].keys() == set(CRIT)
    changed = tmp_path / "changed"
    shutil.copytree(one, changed)
    meta = json.loads((changed / "study.json").read_text())
    meta["study"]["origin"] = "elsewhere"  # a key the rebuilt study does not have
    (changed / "study.json").write_text(json.dumps(meta))
    data = analyse_study(changed, worst=1, resimulate=True).data
    assert data["worst"]["rows"][0]["resimulated"] == {
        "error": "not re-simulated: the study rebuilt from study.json differs from it"
    }


# -- re-simulated worst runs ----------------------------------------------------------------------


def _one_run_folder(out: Path, lockup: float, jerk: float) -> Path:
    d = {
        "study": {"name": "r", "controllers": ["paper"], "scenarios": ["paper-start"],
                  "metrics": ["lockup_time_s", "jerk_max_m_s3"],
                  "criteria": ["lockup_time_s <= 2.5"], "linear": False},
        "sampling": {"method": "mc", "samples": 1, "seed": 1},
        "parameters": {"vehicle.M_v": {"values": [1300.0]}},
    }  # fmt: skip
    study = Study.from_dict(d)
    _prepare_folder(study, out)
    vals = {"vehicle.M_v": 1300.0}
    rec = {"status": "ok", "lockup_time_s": lockup, "jerk_max_m_s3": jerk}
    item = (study.case(0, vals, "paper", 0).label, 0, "paper", "paper-start", vals)
    _write_chunk(out / "results", [_row(item, rec, study.metrics, study.criteria)], _schema(study))
    return out


def test_a_worst_run_is_re_simulated_and_compared_to_its_row(tmp_path: Path) -> None:
    from drivetrain_ctrl.studies.case import simulate_case

    d = Study.from_dict(
        {
            "study": {"name": "r", "controllers": ["paper"], "scenarios": ["paper-start"]},
            "sampling": {"method": "mc", "samples": 1, "seed": 1},
        }
    )
    run = simulate_case(d.case(0, {"vehicle.M_v": 1300.0}, "paper", 0))
    lock, jerk = float(run.metrics["lockup_time_s"]), float(run.metrics["jerk_max_m_s3"])
    assert lock > 2.5  # the run misses the criterion: a worst run
    # the table's lock-up time off by 0.5e-6 and by 1.5e-6 (relative): the re-simulation
    # reproduces a row to 1e-6
    for rel, same in ((0.5e-6, True), (1.5e-6, False)):
        out = _one_run_folder(tmp_path / f"r{rel}", lock * (1.0 + rel), jerk)
        row = analyse_study(out, worst=1).data["worst"]["rows"][0]
        r = row["resimulated"]
        assert r["error"] is None and r["reproduces_table"] is same
        assert r["metrics"] == {"lockup_time_s": pytest.approx(lock, rel=1e-8)}
        assert row["missed"] == ["lockup_time_s <= 2.5"]
        assert row["score"] == pytest.approx((lock * (1 + rel) - 2.5) / 2.5, rel=1e-8)
    # the traces at 100 Hz from the run's own samples
    res = run.result
    tr = row["trace"]
    t = np.arange(float(res.t[0]), float(res.t[-1]) + 1e-12, 0.01)
    assert tr["t_s"] == pytest.approx(t.tolist(), abs=1e-12)
    rpm = 60.0 / (2.0 * math.pi)
    for key, state in (("omega_engine_rpm", "omega_engine"), ("omega_driven_rpm", "omega_primary")):
        want = np.interp(t, np.asarray(res.t), np.asarray(res.state(state))) * rpm
        assert tr[key] == pytest.approx(want.tolist(), rel=1e-8, abs=1e-9)
    assert tr["omega_ref_rpm"] == pytest.approx([run.scenario.reference(x) * rpm for x in t], rel=1e-8)  # fmt: skip
    assert tr["driven_state"] == "omega_primary"
    assert len(tr["clutch_torque_Nm"]) == len(tr["vehicle_accel_m_s2"]) == t.size


def test_equal_indices_are_ranked_by_the_rank_correlation(one: Path, tmp_path: Path) -> None:
    """Two parameters with the same largest first-order index (each drives one criterion's
    metric through the same non-monotone function, on the same set of values): the one with
    the larger |Spearman| on any ranked metric comes first, then the name."""
    out = tmp_path / "tie"
    shutil.copytree(one, out)
    df = pd.read_parquet(out / "results")
    rng = np.random.default_rng(4)
    n = len(df)
    a = rng.permutation(np.linspace(0.0, 1.0, n))
    b = rng.permutation(a)
    df["param:vehicle.M_v"], df["param:clutch.k12_max"] = a, b
    df["status"] = "ok"
    df["lockup_time_s"] = (a - 0.5) ** 2
    df["jerk_max_m_s3"] = (b - 0.5) ** 2
    df["engine_speed_min_rpm"] = a + 3.0 * rng.random(n)  # a weak monotone effect of M_v
    df["controller"] = "paper"  # one group
    for f in (out / "results").glob("chunk-*.parquet"):
        f.unlink()
    df.to_parquet(out / "results" / "chunk-0.parquet")
    e = analyse_study(out, resimulate=False).data["sensitivity"][0]
    r = {x["parameter"]: x for x in e["ranking"]}
    m, k = r["vehicle.M_v"], r["clutch.k12_max"]
    assert m["sobol_first_max"] == k["sobol_first_max"]  # the same sorted (x, y) pairs
    assert (m["on_metric"], k["on_metric"]) == ("lockup_time_s", "jerk_max_m_s3")
    rho = {
        p: max(abs(stats.spearmanr(x, df[c]).statistic) for c in e["ranked_on"])
        for p, x in (("vehicle.M_v", a), ("clutch.k12_max", b))
    }
    assert m["abs_spearman_max"] == pytest.approx(rho["vehicle.M_v"], rel=1e-8)
    assert rho["vehicle.M_v"] > rho["clutch.k12_max"] + 0.1
    assert [x["parameter"] for x in e["ranking"]] == ["vehicle.M_v", "clutch.k12_max"]
