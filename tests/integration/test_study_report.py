"""The study report (issue 23 item 5): ``drivetrain-ctrl study report DIR`` writes report.html,
report.pdf and data.json; the numbers in data.json are checked against values computed here from
the table (pass rates and Wilson intervals, rank correlations, failure counts).

Synthetic folders are written with the runner's own writers (``_prepare_folder``, ``_row``,
``_write_chunk``) from made-up records, with and without paired linear ``lin:`` columns and with
failed rows; one real small study runs on an in-process Dask client."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from drivetrain_ctrl.cli import main
from drivetrain_ctrl.reporting.study_report import (
    STUDY_SECTIONS,
    StudyReportError,
    build_study_report,
)
from drivetrain_ctrl.studies.analysis import (
    LINEAR_PLOTTED,
    MIN_ROWS,
    analyse_study,
    first_order_index,
)
from drivetrain_ctrl.studies.case import LINEAR_FIGURES
from drivetrain_ctrl.studies.runner import (
    _prepare_folder,
    _row,
    _schema,
    _write_chunk,
    read_results,
    run_study,
)
from drivetrain_ctrl.studies.study import Study, load_study, sample_table

SYNTH = {
    "study": {
        "name": "synthetic",
        "model": "reduced",
        "controllers": ["paper", "pi"],
        "scenarios": ["paper-start"],
        "metrics": ["lockup_time_s", "jerk_max_m_s3", "engine_speed_min_rpm"],
        "criteria": ["lockup_time_s <= 2.6", "jerk_max_m_s3 <= 20"],
    },
    "sampling": {"method": "lhs", "samples": 40, "seed": 7},
    "parameters": {
        "vehicle.M_v": {"dist": "uniform", "low": 1100.0, "high": 1500.0},
        "clutch.k12_max": {"dist": "uniform", "low": 200.0, "high": 300.0},
    },
}


def _record(sample: int, c: str, vals: dict[str, float]) -> dict[str, Any]:
    """A made-up record: lock-up time grows with the mass, jerk falls with the capacity, Ms
    rises with it; some samples fail (two kinds of reason, numbers in the message), one never
    locks up, one has no judder margin."""
    m, k = vals["vehicle.M_v"], vals["clutch.k12_max"]
    if sample % 9 == 4:
        return {"status": "failed", "error": f"ZenoError: Zeno at t = {1 + sample / 100:.2f} s"}
    if sample % 13 == 6 and c == "pi":
        return {"status": "failed", "error": f"invalid input: vehicle.M_v = {-m:.1f}: must be > 0"}
    lock = None if (sample == 11 and c == "paper") else 2.0 + (m - 1100.0) / 500.0
    return {
        "status": "ok",
        "lin:Ms": 1.2 + k / 200.0,
        "lin:gain_margin": 3.0 + 0.001 * sample,
        "lin:judder_margin": None if sample == 3 else 2.0 - sample / 100.0,
        "lockup_time_s": lock,
        "jerk_max_m_s3": (15.0 + (300.0 - k) / 10.0) if c == "paper" else 10.0 + (300.0 - k) / 5.0,
        "engine_speed_min_rpm": 900.0 - 0.01 * sample,
    }


def _synthetic(out: Path, *, lin: bool, all_failed: bool = False) -> Path:
    """A study folder written the way the runner writes it (two chunks)."""
    study = Study.from_dict({**SYNTH, "study": {**SYNTH["study"], "linear": lin}})
    samples = _prepare_folder(study, out)
    schema = _schema(study)
    rows = []
    for i in range(study.samples):
        vals = {k: float(v) for k, v in samples.iloc[i].items()}
        for c in study.controller_names:
            case = study.case(i, vals, c, 0)
            rec = (
                {"status": "failed", "error": "RuntimeError: step size too small"}
                if all_failed
                else _record(i, c, vals)
            )
            item = (case.label, i, c, "paper-start", vals)
            rows.append(_row(item, rec, study.metrics, study.criteria, lin))
    half = len(rows) // 2
    _write_chunk(out / "results", rows[:half], schema)
    _write_chunk(out / "results", rows[half:], schema)
    return out


@pytest.fixture(scope="module")
def synth(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _synthetic(tmp_path_factory.mktemp("synth") / "study", lin=False)


@pytest.fixture(scope="module")
def synth_lin(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _synthetic(tmp_path_factory.mktemp("synth_lin") / "study", lin=True)


@pytest.fixture(scope="module")
def synth_report(synth: Path) -> Any:
    """The analysis only (no files): what data.json holds."""
    return analyse_study(synth, resimulate=False)


@pytest.fixture(scope="module")
def synth_files(synth: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The report written by the command (the three files)."""
    out = tmp_path_factory.mktemp("synth_cli") / "rep"
    assert main(["study", "report", str(synth), "--out", str(out), "--no-resimulate"]) == 0
    return out


def _crit_met(df: pd.DataFrame, metric: str, op: str, thr: float) -> np.ndarray:
    v = df[metric].to_numpy(dtype=float)
    with np.errstate(invalid="ignore"):
        met = (v <= thr) if op == "<=" else (v >= thr)
    return (df["status"] == "ok").to_numpy() & met & np.isfinite(v)


# -- data.json against the table ----------------------------------------------------------------
def test_pass_rates_and_wilson_intervals_equal_those_computed_from_the_table(
    synth: Path, synth_report: Any
) -> None:
    df = read_results(synth)
    data = synth_report.data
    assert [r["group"] for r in data["pass_rates"]] == ["paper", "pi"]
    for r in data["pass_rates"]:
        sub = df[df["controller"] == r["controller"]]
        k, n = int(sub["pass"].sum()), len(sub)
        ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
        assert (r["n"], r["passed"]) == (n, k) and 0 < k < n
        assert r["rate"] == pytest.approx(k / n, rel=1e-8)
        assert r["ci_low"] == pytest.approx(ci.low, rel=1e-8)
        assert r["ci_high"] == pytest.approx(ci.high, rel=1e-8)
        # each criterion on its own, from its metric (a run missing one still meets the other)
        met = _crit_met(sub, "jerk_max_m_s3", "<=", 20.0)
        e = r["criteria"]["jerk_max_m_s3 <= 20"]
        assert e["passed"] == int(met.sum())
        assert e["ci_high"] == pytest.approx(
            stats.binomtest(int(met.sum()), n).proportion_ci(method="wilson").high, rel=1e-8
        )
    paper = data["pass_rates"][0]
    assert paper["criteria"]["lockup_time_s <= 2.6"]["passed"] > paper["passed"]


def test_rank_correlations_and_ranking_equal_scipy_on_the_table(
    synth: Path, synth_report: Any
) -> None:
    df = read_results(synth)
    data = synth_report.data
    sens = {s["group"]: s for s in data["sensitivity"]}
    sub = df[df["controller"] == "paper"]
    ok = np.isfinite(sub["lockup_time_s"].to_numpy())
    x = sub["param:vehicle.M_v"].to_numpy()[ok]
    y = sub["lockup_time_s"].to_numpy()[ok]
    e = sens["paper"]["metrics"]["lockup_time_s"]["vehicle.M_v"]
    assert e["n"] == int(ok.sum()) < len(sub)  # failed rows and the undefined lock-up left out
    assert e["spearman"] == pytest.approx(stats.spearmanr(x, y).statistic, rel=1e-8)
    assert e["spearman"] == pytest.approx(1.0)  # lock-up time is a rising function of the mass
    # the Sobol index is SALib's RBD-FAST on the same runs (first_order_index), with its interval
    s1, conf = first_order_index(x, y)
    assert (e["sobol_first"], e["sobol_first_conf"]) == (pytest.approx(s1), pytest.approx(conf))
    assert e["sobol_first"] > 0.9 and 0.0 < e["sobol_first_conf"] < 0.5
    assert sens["paper"]["metrics"]["jerk_max_m_s3"]["clutch.k12_max"]["spearman"] == pytest.approx(
        -1.0
    )
    # the mass drives the lock-up time, the capacity the jerk: both rank high, nothing else exists
    ranking = sens["paper"]["ranking"]
    assert {r["parameter"] for r in ranking} == {"vehicle.M_v", "clutch.k12_max"}
    assert all(r["sobol_first_max"] > 0.9 for r in ranking)
    assert sens["paper"]["ranked_on"] == ["lockup_time_s", "jerk_max_m_s3"]


def test_failure_reasons_are_counted_like_the_table(synth: Path, synth_report: Any) -> None:
    df = read_results(synth)
    f = synth_report.data["failures"]
    bad = df[df["status"] != "ok"]
    zeno = bad["error"].str.startswith("ZenoError").sum()
    invalid = bad["error"].str.startswith("invalid input").sum()
    assert zeno > 1 and invalid > 0 and zeno + invalid == len(bad)
    counts = {e["reason"]: e["count"] for e in f["runs"]}
    # the numbers in the messages do not split one cause into many lines
    assert counts == {
        "failed: ZenoError: Zeno at t = # s": zeno,
        "failed: invalid input: vehicle.M_v = #: must be > #": invalid,
    }
    assert f["status_counts"] == {"failed": len(bad), "ok": len(df) - len(bad)}
    for g in f["criteria"]:
        sub = df[df["controller"] == g["group"]]
        assert g["not_finished"] == int((sub["status"] != "ok").sum())
        assert g["criteria"]["lockup_time_s <= 2.6"] == int(
            (~_crit_met(sub, "lockup_time_s", "<=", 2.6)).sum()
        )


def test_histograms_leave_out_failed_and_undefined_runs(synth: Path, synth_report: Any) -> None:
    df = read_results(synth)
    h = synth_report.data["histograms"]["lockup_time_s"]
    sub = df[df["controller"] == "paper"]
    fin = sub["lockup_time_s"].dropna().to_numpy()
    g = h["groups"]["paper"]
    assert sum(g["counts"]) == g["n"] == fin.size and g["undefined"] == len(sub) - fin.size
    assert g["median"] == pytest.approx(float(np.median(fin)), rel=1e-8)
    assert h["edges"][0] == pytest.approx(df["lockup_time_s"].min(), rel=1e-8)


def test_the_report_is_deterministic_and_self_contained(
    synth: Path, synth_files: Path, tmp_path: Path
) -> None:
    b = build_study_report(synth, out=tmp_path / "b", resimulate=False)
    assert (synth_files / "data.json").read_bytes() == (tmp_path / "b" / "data.json").read_bytes()
    assert json.loads((synth_files / "data.json").read_text()) == b.data
    text = (synth_files / "report.html").read_text()
    assert "http://" not in text and "https://" not in text and "<script" not in text
    names = {"pass_rates", "histograms", "scatter", "sensitivity", "failures"}
    assert set(b.plot()) == names  # no linear figure, no re-simulated runs
    assert text.count('src="data:image/png;base64,') == len(names)
    for title in STUDY_SECTIONS:
        assert f"<h2>{title}</h2>" in text
    assert "Wilson" in text and "first-order" in text and "SALib.analyze.rbd_fast" in text
    assert "S1 1.00 +/- 0.0" in text  # the index with its interval in the table
    assert (synth_files / "report.pdf").read_bytes()[:5] == b"%PDF-"


def test_a_folder_without_lin_columns_says_so(synth_report: Any, synth_files: Path) -> None:
    lin = synth_report.data["linear"]
    assert lin["available"] is False and lin["columns"] == []
    assert "no lin: columns" in lin["reason"]
    html = (synth_files / "report.html").read_text()
    assert "Not available: the results table has no paired linear figures" in html


def test_lin_columns_are_correlated_with_the_nonlinear_outcomes(synth_lin: Path) -> None:
    rep = analyse_study(synth_lin, resimulate=False)
    df = read_results(synth_lin)
    lin = rep.data["linear"]
    assert lin["available"] and lin["columns"] == sorted(LINEAR_FIGURES)
    assert lin["plotted"] == [c for c in LINEAR_PLOTTED if c in LINEAR_FIGURES]
    assert lin["outcomes"] == ["lockup_time_s", "jerk_max_m_s3", "pass"]
    g = next(x for x in lin["groups"] if x["group"] == "pi")
    sub = df[(df["controller"] == "pi") & (df["status"] != "failed")]
    x, y = sub["lin:Ms"].to_numpy(), sub["jerk_max_m_s3"].to_numpy()
    ok = np.isfinite(x) & np.isfinite(y)
    e = g["correlations"]["lin:Ms"]["jerk_max_m_s3"]
    assert e["n"] == int(ok.sum())
    assert e["spearman"] == pytest.approx(stats.spearmanr(x[ok], y[ok]).statistic, rel=1e-8)
    assert e["spearman"] == pytest.approx(-1.0)  # Ms rises with the capacity, jerk falls
    assert g["correlations"]["lin:judder_margin"]["lockup_time_s"]["n"] == int(ok.sum()) - 1
    pooled = lin["groups"][-1]  # over every finished run of both controllers
    done = df[df["status"] != "failed"]
    x, y = done["lin:Ms"].to_numpy(), done["lockup_time_s"].to_numpy()
    ok = np.isfinite(x) & np.isfinite(y)
    assert pooled["group"] == "all runs" and len(lin["groups"]) == 3
    assert pooled["correlations"]["lin:Ms"]["lockup_time_s"]["n"] == int(ok.sum())
    assert pooled["correlations"]["lin:Ms"]["lockup_time_s"]["spearman"] == pytest.approx(
        stats.spearmanr(x[ok], y[ok]).statistic, rel=1e-8
    )
    assert "linear" in rep.plot()
    assert rep.data["points"]["lin"]["lin:Ms"][0] == pytest.approx(float(df["lin:Ms"].iloc[0]))


def test_a_folder_where_every_run_failed_still_gives_a_report(tmp_path: Path) -> None:
    folder = _synthetic(tmp_path / "bad", lin=True, all_failed=True)
    rep = build_study_report(folder)
    d = rep.data
    assert d["rows"]["failed"] == d["rows"]["total"] == 80 and d["rows"]["passed"] == 0
    assert all(r["passed"] == 0 and r["ci_low"] == 0.0 for r in d["pass_rates"])
    assert d["failures"]["runs"] == [
        {"reason": "failed: RuntimeError: step size too small", "count": 80,
         "by_group": {"paper": 40, "pi": 40}, "example_key": "s000000|paper|paper-start",
         "example_error": "RuntimeError: step size too small"}
    ]  # fmt: skip
    assert d["worst"]["rows"] == []  # nothing finished: nothing to re-simulate
    assert set(rep.plot()) == {"pass_rates", "scatter", "sensitivity", "linear", "failures"}
    assert all(f.exists() for f in rep.files)


# -- errors and the command ---------------------------------------------------------------------
def test_a_bad_folder_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(StudyReportError, match="not a directory"):
        analyse_study(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(StudyReportError, match="no study.json"):
        analyse_study(tmp_path / "empty")
    _prepare_folder(Study.from_dict(SYNTH), tmp_path / "norun")
    with pytest.raises(StudyReportError, match="no results"):
        analyse_study(tmp_path / "norun")
    with pytest.raises(StudyReportError, match="worst = -1"):
        analyse_study(tmp_path / "norun", worst=-1)
    assert main(["study", "report", str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err
    assert "error: study folder" in err and "nope" in err and "Traceback" not in err


def test_the_study_report_is_exported_from_reporting_like_the_controller_report() -> None:
    import drivetrain_ctrl.reporting as reporting
    from drivetrain_ctrl.reporting import study_report

    assert reporting.build_study_report is study_report.build_study_report
    assert reporting.StudyReport is study_report.StudyReport
    assert {"build_study_report", "StudyReport", "build_report", "Report"} <= set(reporting.__all__)


def test_the_command_writes_the_three_files(synth_files: Path) -> None:
    for name in ("data.json", "report.html", "report.pdf"):
        assert (synth_files / name).stat().st_size > 0
    assert json.loads((synth_files / "data.json").read_text())["study"]["name"] == "synthetic"


# -- a real study -------------------------------------------------------------------------------
REAL = """
[study]
name = "tiny-report"
model = "reduced"
controllers = ["paper", "pi"]
scenarios = ["paper-start"]
metrics = ["lockup_time_s", "jerk_max_m_s3", "engine_speed_min_rpm"]
criteria = ["lockup_time_s <= 2.3", "jerk_max_m_s3 <= 25"]
t_end = 3.0

[sampling]
method = "lhs"
samples = 14
seed = 5

[parameters."vehicle.M_v"]      # a wide normal: a few samples are masses the model refuses
dist = "normal"
mean = 1300.0
std = 900.0

[parameters."clutch.k12_max"]
dist = "uniform"
low = 200.0
high = 300.0
"""


@pytest.fixture(scope="module")
def real(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    from dask.distributed import Client, LocalCluster

    tmp = tmp_path_factory.mktemp("real")
    (tmp / "s.toml").write_text(REAL)
    cluster = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    )
    client = Client(cluster)
    try:
        run_study(tmp / "s.toml", out=tmp / "out", client=client, progress=False)
    finally:
        client.close()
        cluster.close()
    yield tmp / "out"


def test_a_real_study_report_re_simulates_its_worst_runs(real: Path) -> None:
    df = read_results(real)
    rep = analyse_study(real, worst=1)
    d = rep.data
    assert d["rows"]["total"] == 28 and d["rows"]["failed"] == int((df["status"] == "failed").sum())
    assert 0 < d["rows"]["failed"] < 8  # the refused masses are failed rows, and break nothing
    rows = d["worst"]["rows"]
    assert [r["controller"] for r in rows] == ["paper", "pi"]
    for r in rows:
        row = df[df["key"] == r["key"]].iloc[0]
        assert row["status"] != "failed"
        assert r["params"]["vehicle.M_v"] == pytest.approx(row["param:vehicle.M_v"], rel=1e-8)
        assert r["resimulated"]["error"] is None and r["resimulated"]["reproduces_table"] is True
        tr = r["trace"]
        assert len(tr["t_s"]) == len(tr["clutch_torque_Nm"]) == len(tr["vehicle_accel_m_s2"]) > 100
        assert tr["t_s"][-1] == pytest.approx(3.0, abs=0.011)
        assert max(tr["omega_engine_rpm"]) > 1000 and max(tr["clutch_torque_Nm"]) > 10
        # the worst of its controller: no finished run of it misses a criterion by more
        sub = df[(df["controller"] == r["controller"]) & (df["status"] != "failed")]
        worst_lock = (sub["lockup_time_s"].fillna(np.inf) - 2.3) / 2.3
        worst_jerk = (sub["jerk_max_m_s3"] - 25.0) / 25.0
        expected = max(worst_lock.max(), worst_jerk.max())
        if math.isinf(expected):  # an undefined lock-up is the worst (None in JSON)
            assert r["score"] is None and math.isnan(row["lockup_time_s"])
        else:
            assert r["score"] == pytest.approx(expected, rel=1e-8)
    samples = sample_table(load_study(real.parent / "s.toml"))
    assert rows[0]["params"]["clutch.k12_max"] == pytest.approx(
        samples.loc[rows[0]["sample"], "clutch.k12_max"], rel=1e-8
    )
    assert "worst" in rep.plot() and not math.isnan(d["pass_rates"][0]["ci_high"])
    # the runner's paired linear figures are correlated with the outcomes
    lin = d["linear"]
    assert lin["available"] and "lin:Ms" in lin["columns"] and "linear" in rep.plot()
    g = lin["groups"][0]
    sub = df[(df["controller"] == g["controller"]) & (df["status"] != "failed")]
    x, y = sub["lin:Ms"].to_numpy(), sub["jerk_max_m_s3"].to_numpy()
    ok = np.isfinite(x) & np.isfinite(y)
    assert g["correlations"]["lin:Ms"]["jerk_max_m_s3"]["n"] == int(ok.sum()) >= MIN_ROWS
    assert g["correlations"]["lin:Ms"]["jerk_max_m_s3"]["spearman"] == pytest.approx(
        stats.spearmanr(x[ok], y[ok]).statistic, rel=1e-8
    )


def test_a_study_that_cannot_be_rebuilt_is_reported_without_re_simulation(
    synth: Path, tmp_path: Path
) -> None:
    import shutil

    folder = tmp_path / "moved"
    shutil.copytree(synth, folder)
    meta = json.loads((folder / "study.json").read_text())
    meta["study"]["controllers"] = ["paper", str(tmp_path / "gone.toml")]  # a file since moved
    (folder / "study.json").write_text(json.dumps(meta))
    d = analyse_study(folder, worst=1).data
    assert d["study"]["criteria"] == ["lockup_time_s <= 2.6", "jerk_max_m_s3 <= 20"]
    assert [r["controller"] for r in d["worst"]["rows"]] == ["paper", "pi"]
    for r in d["worst"]["rows"]:
        assert r["trace"] is None
        assert r["resimulated"]["error"].startswith("not re-simulated: the study in study.json")
        assert "gone.toml" in r["resimulated"]["error"]
    # the rest is computed from the table as before
    ref = analyse_study(synth, resimulate=False).data
    assert d["pass_rates"] == ref["pass_rates"] and d["sensitivity"] == ref["sensitivity"]
