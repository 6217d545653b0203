"""Figures live in one layer: only ``drivetrain_ctrl.reporting`` imports matplotlib, and its
figures are plain ``Figure`` objects (no pyplot registry: nothing to close in batch runs)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import drivetrain_ctrl
from drivetrain_ctrl.sim.run import run_scenario

PKG = Path(drivetrain_ctrl.__file__).parent


def _matplotlib_imports(path: Path) -> list[int]:
    lines = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        else:
            continue
        if any(n == "matplotlib" or n.startswith("matplotlib.") for n in names):
            lines.append(node.lineno)
    return lines


def test_only_the_reporting_layer_imports_matplotlib() -> None:
    reporting = PKG / "reporting"
    offenders = {
        str(p.relative_to(PKG)): ln
        for p in sorted(PKG.rglob("*.py"))
        if reporting not in p.parents and (ln := _matplotlib_imports(p))
    }
    assert offenders == {}, f"matplotlib imported outside reporting/ (file: lines): {offenders}"
    assert _matplotlib_imports(reporting / "figures.py")  # the check itself sees imports


def test_loop_figures_are_plain_figures_saved_as_png(tmp_path: Path) -> None:
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    from drivetrain_ctrl.reporting.figures import plot_loop, plot_nyquist, plot_root_locus

    before = plt.get_fignums()
    w = np.logspace(-1, 2, 50)
    L = 10.0 / (1j * w * (1j * w + 1.0))
    db = 20 * np.log10(np.abs(L))
    ph = np.degrees(np.unwrap(np.angle(L)))
    figs = [
        plot_loop(w, {"L": (db, ph)}, title="t", poles=[(-1.0, 3.0), (-1.0, -3.0)],
                  path=tmp_path / "bode.png"),
        plot_loop(w, {}, title="poles only", poles=[(-2.0, 0.0)]),
        plot_nyquist(L.real, L.imag, encirclements=0, open_loop_unstable_poles=0,
                     closed_loop_unstable_poles=0, path=tmp_path / "nyq.png"),
        plot_root_locus([(1.0, [(-1.0, 0.0)], "a"), (2.0, [(-2.0, 1.0)], "b")],
                        parameter="k", unit="-", path=tmp_path / "rl.png"),
    ]  # fmt: skip
    assert all(isinstance(f, Figure) for f in figs)
    assert plt.get_fignums() == before
    for name in ("bode.png", "nyq.png", "rl.png"):
        assert (tmp_path / name).read_bytes().startswith(b"\x89PNG")


def test_root_locus_legend_only_with_several_modes() -> None:
    from drivetrain_ctrl.reporting.figures import plot_root_locus

    one = plot_root_locus([(1.0, [(-1.0, 0.0)], "a")], parameter="k", unit="-")
    two = plot_root_locus([(1.0, [(-1.0, 0.0)], "a"), (2.0, [(-2.0, 0.0)], "b")],
                          parameter="k", unit="-")  # fmt: skip
    assert one.axes[0].get_legend() is None
    assert [t.get_text() for t in two.axes[0].get_legend().get_texts()] == ["mode 1", "mode 2"]


def test_the_import_scan_sees_nested_imports(tmp_path: Path) -> None:
    p = tmp_path / "x.py"
    p.write_text("import numpy\nfrom os import path\n")
    assert _matplotlib_imports(p) == []
    p.write_text("def f():\n    from matplotlib.figure import Figure\n")
    assert _matplotlib_imports(p) == [2]


def test_plot_functions_name_bad_input() -> None:
    from drivetrain_ctrl.reporting.figures import plot_loop, plot_root_locus

    with pytest.raises(ValueError, match="points is empty"):
        plot_root_locus([], parameter="k", unit="-")
    with pytest.raises(ValueError, match=r"bode\['L'\] has 2 magnitudes and 3 phases for 3"):
        plot_loop([1.0, 2.0, 3.0], {"L": ([0.0, 1.0], [0.0, 1.0, 2.0])}, title="t")


def test_plot_paths_must_be_png_and_pdf_blocks_are_checked(tmp_path) -> None:
    """A plot never overwrites a file of another kind (e.g. a CSV) with PNG bytes."""
    from drivetrain_ctrl.plant.drivetrain import Drivetrain
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.reporting.figures import write_report_pdf
    from drivetrain_ctrl.scenarios.scenario import load_scenario

    res = run_scenario(
        load_scenario("tip-in"), Drivetrain(default_params(), kind="reduced"), t_end=0.2
    )
    data = tmp_path / "data.csv"
    data.write_text("keep", encoding="utf-8")
    for bad in (data, tmp_path / "x.pdf", 123):
        with pytest.raises(ValueError, match="give a file name ending in .png"):
            res.plot(bad)
    assert data.read_text(encoding="utf-8") == "keep"
    res.plot(tmp_path / "ok.png")
    assert (tmp_path / "ok.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match=r"blocks\[0\] = \('x', 'hi'\)"):
        write_report_pdf([("x", "hi")], tmp_path / "t.pdf")
    with pytest.raises(ValueError, match=r"blocks\[1\] = \('figure', 'not a figure'\)"):
        write_report_pdf([("p", "hi"), ("figure", "not a figure")], tmp_path / "t.pdf")
    assert not (tmp_path / "t.pdf").exists()


def test_plot_engagement_checks_runs_lockups_and_reference() -> None:
    from drivetrain_ctrl.reporting.figures import plot_engagement

    for runs in ("x", [("a", 1)], {"a": 1}):
        with pytest.raises(ValueError, match="give a list of .label, SimulationResult. pairs"):
            plot_engagement(runs)  # type: ignore[arg-type]
