"""The controller report (report.py): files, sections, data keys, determinism, argument errors."""

from __future__ import annotations

import json
import math

import matplotlib
import numpy as np
import pytest

from drivetrain_ctrl.control.laws import ControllerError
from drivetrain_ctrl.reporting.controller_report import MARGIN_KEYS, SECTIONS, build_report

matplotlib.use("Agg")

#: the scalar figures among the margin keys (the others are lists)
SCALAR_MARGINS = tuple(
    k for k in MARGIN_KEYS if k not in ("closed_loop_poles", "natural_frequencies_hz")
)


@pytest.fixture(scope="module")
def paper_report(tmp_path_factory):
    return build_report(controller="paper", model="reduced", out=tmp_path_factory.mktemp("paper"))


def _check_report(rep, controller: str) -> dict:
    out = rep.out
    for name in ("data.json", "report.html", "report.pdf"):
        assert (out / name).is_file() and (out / name) in rep.files
    data = json.loads((out / "data.json").read_text())
    assert data == rep.data
    for mode in ("slip", "lock"):
        entry = data["modes"][mode][controller]
        for k in MARGIN_KEYS:
            assert k in entry, (mode, k)
    slip = data["modes"]["slip"][controller]
    for k in SCALAR_MARGINS:
        assert isinstance(slip[k], float) and math.isfinite(slip[k]), k
    assert slip["closed_loop_poles"] and all(p["real"] < 0 for p in slip["closed_loop_poles"])
    for k in ("L", "S", "T"):
        assert set(slip["bode"][k]) == {"omega", "magnitude_db", "phase_deg"}
        assert set(slip["transfer_functions"][k]) == {"num", "den", "dt"}
    # linear.trim_tf's leading terms: no spurious leading zero in any numerator or denominator
    for k, tf in slip["transfer_functions"].items():
        assert tf["den"][0] != 0.0, k
        assert tf["num"][0] != 0.0 or tf["num"] == [0.0], k
    assert slip["nyquist"]["real"] and slip["root_locus"]["gain"]["points"]
    assert slip["root_locus"]["mu_slope"]["points"]
    lock = data["modes"]["lock"][controller]
    for k in MARGIN_KEYS:
        assert lock[k] is None and "open" in lock["reasons"][k]
    assert lock["shuffle_modes"] and lock["shuffle_modes"][0]["natural_frequency_hz"] > 0
    assert lock["breakaway_margins"]["clutch"]["margin"] > 0
    assert data["engagement_metrics"]["lockup_time_s"] is not None
    steps = data["linear_vs_nonlinear"]["steps"]
    assert steps and all(len(s["linear_rpm"]) == len(s["nonlinear_rpm"]) for s in steps.values())
    assert all(s["statement"] for s in steps.values())
    return data


def test_report_paper_reduced(paper_report):
    data = _check_report(paper_report, "paper")
    html = (paper_report.out / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 5
    for title in SECTIONS:
        assert title in html, title
    pdf = (paper_report.out / "report.pdf").read_bytes()
    assert pdf.startswith(b"%PDF")
    assert pdf.count(b"/Type /Page") - pdf.count(b"/Type /Pages") >= 4
    # the small step stays in the linear range for law (6)
    assert data["linear_vs_nonlinear"]["steps"]["small"]["agree"]


def test_report_plot_returns_figures(paper_report):
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    before = plt.get_fignums()
    figs = paper_report.plot()
    assert {"bode", "root_locus", "nyquist", "step", "engagement", "lock"} <= set(figs)
    assert all(isinstance(f, Figure) for f in figs.values())
    assert plt.get_fignums() == before  # plain figures: none left open in pyplot
    # drawn from the data: the Bode axes hold L, S, T over the stored frequency grid
    bode = paper_report.data["modes"]["slip"]["paper"]["bode"]
    lines = figs["bode"].axes[0].get_lines()
    assert [ln.get_label() for ln in lines[:3]] == ["L", "S", "T"]
    assert np.allclose(lines[0].get_xdata(), bode["L"]["omega"])


def test_report_data_is_deterministic(paper_report, tmp_path):
    again = build_report(controller="paper", model="reduced", out=tmp_path / "again")
    a = (paper_report.out / "data.json").read_bytes()
    b = (again.out / "data.json").read_bytes()
    assert a == b


def test_report_pi_10ms(tmp_path):
    rep = build_report(controller="pi-10ms", out=tmp_path)
    data = _check_report(rep, "pi-10ms")
    assert data["modes"]["slip"]["pi-10ms"]["sample_period_s"] == pytest.approx(0.01)
    assert data["modes"]["slip"]["pi-10ms"]["root_locus"]["gain"]["parameter"] == "gain_factor"


def test_report_pi_small_step_agrees_with_the_linear_prediction(tmp_path):
    """The PI's step reaches the controller in the nonlinear run too (its integrator state is
    matched with the nominal reference): a small reference step stays within 10 % of the linear
    closed-loop prediction."""
    rep = build_report(controller="pi", out=tmp_path)
    small = rep.data["linear_vs_nonlinear"]["steps"]["small"]
    assert small["agree"] and small["relative_peak_difference"] < 0.1


def test_report_bad_arguments(tmp_path):
    with pytest.raises(ControllerError, match="controller 'nope'"):
        build_report(controller="nope", out=tmp_path)
    with pytest.raises(ValueError, match="model = 'medium'"):
        build_report(model="medium", out=tmp_path)
    with pytest.raises(ValueError, match="scenario 'nope'"):
        build_report(scenario="nope", out=tmp_path)
    with pytest.raises(ValueError, match="scenario = 'engage-ramp'"):
        build_report(scenario="engage-ramp", out=tmp_path)
    with pytest.raises(ValueError, match="params = 'nope'"):
        build_report(params="nope", out=tmp_path)
    assert not (tmp_path / "data.json").exists()


def test_report_full_model(tmp_path):
    rep = build_report(controller="paper", model="full", out=tmp_path)
    _check_report(rep, "paper")


def test_report_simulates_the_nominal_step_run_once(tmp_path, monkeypatch):
    """The nominal run of the step comparison is shared by the step sizes, and the scenario's
    controller is built once (the step runs use a state-matched copy of it)."""
    from drivetrain_ctrl.control.laws import ControllerSpec
    from drivetrain_ctrl.reporting import controller_analysis as A
    from drivetrain_ctrl.reporting import controller_report as R

    calls = {"simulate": 0, "build": 0}
    sim, build = A.simulate, ControllerSpec.build

    def counting_simulate(*a, **kw):
        calls["simulate"] += 1
        return sim(*a, **kw)

    def counting_build(self, *a, **kw):
        calls["build"] += 1
        return build(self, *a, **kw)

    monkeypatch.setattr(A, "simulate", counting_simulate)
    monkeypatch.setattr(ControllerSpec, "build", counting_build)
    R.build_report(controller="paper", out=tmp_path)
    assert calls == {"simulate": 1 + len(A.STEP_SIZES_RPM), "build": 1}


def test_report_on_a_scenario_too_short_for_the_step_responses(tmp_path):
    import dataclasses

    from drivetrain_ctrl.scenarios.scenario import load_scenario

    sc = dataclasses.replace(load_scenario("paper-start"), name="short", t_end=0.6)
    with pytest.raises(ValueError, match=r"scenario 'short': t_end = 0.6 s leaves no time"):
        build_report(controller="paper", scenario=sc, model="reduced", out=tmp_path / "r")


def test_the_metrics_table_has_units_and_definitions(paper_report) -> None:
    """Section 8: every key of the run's metrics, in the order of sim.metrics.METRICS, with its
    unit and its definition from there (issue 19, item 7)."""
    import html as html_mod

    from drivetrain_ctrl.reporting.controller_report import _sections
    from drivetrain_ctrl.sim.metrics import METRICS

    ((caption, rows),) = next(t for s, _, t, _ in _sections(paper_report.data) if s == SECTIONS[7])
    assert caption == "Engagement metrics"
    assert rows[0] == ["metric", "value", "unit", "definition"]
    assert [r[0] for r in rows[1:]] == list(METRICS)
    for name, _, unit, definition in rows[1:]:
        assert unit == (METRICS[name].unit or "-") and definition == METRICS[name].definition
    page = (paper_report.out / "report.html").read_text(encoding="utf-8")
    assert html_mod.escape(METRICS["torque_match_rms_Nm"].definition) in page
