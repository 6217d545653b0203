"""What the figures show (issue 19, item 8): a closed-loop overview names its scenario and
controller and draws the reference and the controller's command; an open-loop one does neither."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")


def _labels(fig) -> list[str]:  # type: ignore[no-untyped-def]
    return [ln.get_label() for ax in fig.axes for ln in ax.get_lines()]


@pytest.fixture
def captured(monkeypatch):  # type: ignore[no-untyped-def]
    """The overview figures the CLI draws (plot_simulation wrapped)."""
    import drivetrain_ctrl.reporting.figures as F

    figs = []
    orig = F.plot_simulation

    def keep(*a, **kw):  # type: ignore[no-untyped-def]
        fig = orig(*a, **kw)
        figs.append(fig)
        return fig

    monkeypatch.setattr(F, "plot_simulation", keep)
    return figs


def test_closed_loop_overview_names_scenario_and_controller(tmp_path: Path, captured) -> None:  # type: ignore[no-untyped-def]
    from drivetrain_ctrl.cli import main

    code = main(
        ["simulate", "--scenario", "paper-start", "--controller", "pi", "--model", "reduced",
         "--t-end", "1.5", "--out", str(tmp_path / "cl")]
    )  # fmt: skip
    assert code == 0 and (tmp_path / "cl" / "overview.png").is_file()
    (fig,) = captured
    title = fig.get_suptitle()
    assert "paper-start" in title and "controller pi" in title
    labels = _labels(fig)
    assert "engine reference omega_r" in labels
    assert "controller command x_r" in labels
    assert "clutch pedal x_c (actuator)" in labels
    # the reference is drawn from the controller's start on, at 1600 rpm
    ref = next(ln for ax in fig.axes for ln in ax.get_lines()
               if ln.get_label() == "engine reference omega_r")  # fmt: skip
    assert min(ref.get_xdata()) >= 0.5 and max(ref.get_ydata()) == pytest.approx(1600.0)


def test_open_loop_overview_has_no_reference_or_command(tmp_path: Path, captured) -> None:  # type: ignore[no-untyped-def]
    from drivetrain_ctrl.cli import main

    code = main(
        ["simulate", "--scenario", "tip-in", "--model", "reduced", "--t-end", "0.3",
         "--out", str(tmp_path / "ol")]
    )  # fmt: skip
    assert code == 0
    (fig,) = captured
    assert "tip-in" in fig.get_suptitle() and "controller" not in fig.get_suptitle()
    labels = _labels(fig)
    assert "engine reference omega_r" not in labels and "controller command x_r" not in labels
    assert "clutch pedal" in labels


def test_plot_simulation_checks_reference_and_start() -> None:
    from drivetrain_ctrl.plant.drivetrain import Drivetrain
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.reporting.figures import plot_simulation
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.run import run_scenario

    res = run_scenario(
        load_scenario("tip-in"), Drivetrain(default_params(), kind="reduced"), t_end=0.1
    )
    with pytest.raises(ValueError, match="reference = 1600"):
        plot_simulation(res, reference=1600)
    with pytest.raises(ValueError, match="control_start = 'x'"):
        plot_simulation(res, control_start="x")  # type: ignore[arg-type]


def test_report_command_prints_the_judder_threshold(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    from drivetrain_ctrl.cli import main

    assert main(["report", "--controller", "pi", "--model", "full", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("judder threshold: "))
    assert "-0.01 " not in line and "Hz mode crosses" in line
