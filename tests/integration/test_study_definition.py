"""Study definitions (issue 23 item 1): TOML -> Study, samples reproducible from the seed, every
distribution and method as defined, and every bad input rejected before any work, naming the key."""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats

from drivetrain_ctrl.studies.study import (
    Study,
    StudyError,
    load_study,
    row_key,
    sample_table,
)

ROOT = Path(__file__).resolve().parents[2]


def _base() -> dict[str, Any]:
    return {
        "study": {
            "name": "t",
            "model": "reduced",
            "controllers": ["paper", "pi"],
            "scenarios": ["paper-start"],
            "criteria": ["lockup_time_s <= 3.0", "engine_speed_min_rpm >= 700"],
        },
        "sampling": {"method": "lhs", "samples": 64, "seed": 7},
        "parameters": {
            "vehicle.M_v": {"dist": "uniform", "low": 1100.0, "high": 1500.0},
            "clutch.static_ratio": {
                "dist": "truncnormal",
                "mean": 1.1,
                "std": 0.2,
                "low": 1.0,
                "high": 1.4,
            },
            "actuator.omega_a": {"dist": "loguniform", "low": 100.0, "high": 400.0},
            "clutch.k12_max": {"dist": "normal", "mean": 250.0, "std": 10.0},
            "controller.x_r0": {"dist": "values", "values": [0.065, 0.07, 0.075]},
        },
    }


def _with(path: str, value: Any, d: dict[str, Any] | None = None) -> dict[str, Any]:
    """A copy of the base study with the dotted ``path`` set (None: removed)."""
    d = copy.deepcopy(d or _base())
    *head, last = path.split("/")
    node = d
    for k in head:
        node = node[k]
    if value is None:
        node.pop(last)
    else:
        node[last] = value
    return d


def test_the_same_seed_gives_the_same_samples_and_another_seed_others() -> None:
    for method in ("mc", "lhs", "sobol"):
        a = sample_table(Study.from_dict(_with("sampling/method", method)))
        b = sample_table(Study.from_dict(_with("sampling/method", method)))
        c = sample_table(
            Study.from_dict(_with("sampling/seed", 8, _with("sampling/method", method)))
        )
        assert a.equals(b), method
        assert not np.allclose(a.to_numpy(), c.to_numpy()), method
        assert a.shape == (64, 5) and list(a.columns)[0] == "vehicle.M_v"


def test_latin_hypercube_puts_one_sample_in_each_stratum_of_every_parameter() -> None:
    df = sample_table(Study.from_dict(_base()))
    n = len(df)
    u = (df["vehicle.M_v"].to_numpy() - 1100.0) / 400.0
    assert sorted(np.floor(u * n).astype(int)) == list(range(n))
    # the log-uniform parameter: uniform in log(omega_a)
    v = np.log(df["actuator.omega_a"].to_numpy() / 100.0) / math.log(4.0)
    assert sorted(np.floor(v * n).astype(int)) == list(range(n))
    # the truncated normal: one sample per probability stratum of its own distribution
    a, b = (1.0 - 1.1) / 0.2, (1.4 - 1.1) / 0.2
    p = stats.truncnorm.cdf(df["clutch.static_ratio"].to_numpy(), a, b, loc=1.1, scale=0.2)
    assert sorted(np.floor(p * n).astype(int)) == list(range(n))
    assert df["clutch.static_ratio"].between(1.0, 1.4).all()
    assert set(df["controller.x_r0"]) == {0.065, 0.07, 0.075}


def test_monte_carlo_draws_follow_the_distributions() -> None:
    d = _with("sampling/method", "mc", _with("sampling/samples", 4000))
    df = sample_table(Study.from_dict(d))
    # Kolmogorov-Smirnov against each distribution (p-values are not tiny for a correct sampler)
    assert stats.kstest(df["vehicle.M_v"], stats.uniform(1100.0, 400.0).cdf).pvalue > 1e-3
    assert stats.kstest(df["clutch.k12_max"], stats.norm(250.0, 10.0).cdf).pvalue > 1e-3
    assert stats.kstest(df["actuator.omega_a"], stats.loguniform(100.0, 400.0).cdf).pvalue > 1e-3
    counts = df["controller.x_r0"].value_counts()
    assert set(counts.index) == {0.065, 0.07, 0.075} and counts.min() > 1200


def test_a_grid_is_the_full_product_of_the_values() -> None:
    d = _base()
    d["sampling"] = {"method": "grid"}
    d["parameters"] = {
        "vehicle.M_v": {"values": [1200.0, 1300.0, 1400.0]},
        "controller.x_r0": {"dist": "values", "values": [0.065, 0.07]},
    }
    s = Study.from_dict(d)
    df = sample_table(s)
    assert s.samples == 6 and len(df) == 6
    pairs = set(zip(df["vehicle.M_v"], df["controller.x_r0"], strict=True))
    assert pairs == {(m, x) for m in (1200.0, 1300.0, 1400.0) for x in (0.065, 0.07)}
    assert len(s.keys()) == 6 * 2 and s.keys()[0] == row_key(0, "paper", "paper-start")


def test_a_case_carries_the_sample_into_parameters_and_controller_gains() -> None:
    s = Study.from_dict(_base())
    case = s.case(3, {"vehicle.M_v": 1234.0, "controller.x_r0": 0.075}, "pi", 0)
    assert case.overrides == {"vehicle.M_v": 1234.0}
    assert case.controller.name == "pi" and case.controller.x_r0 == 0.075
    assert case.model == "reduced" and case.label == "s000003|pi|paper-start"


@pytest.mark.parametrize(
    ("path", "value", "named"),
    [
        (
            "parameters/clutch.nonsense",
            {"dist": "uniform", "low": 1.0, "high": 2.0},
            "clutch.nonsense",
        ),
        (
            "parameters/vehicle.M_v",
            {"dist": "uniform", "low": 1500.0, "high": 1100.0},
            "vehicle.M_v'.low",
        ),
        (
            "parameters/vehicle.M_v",
            {"dist": "normal", "mean": 1300.0, "std": 0.0},
            "vehicle.M_v'.std",
        ),
        ("parameters/vehicle.M_v", {"dist": "gamma", "low": 1.0}, "vehicle.M_v'.dist"),
        ("parameters/vehicle.M_v", {"dist": "uniform", "low": 1100.0}, "needs 'high'"),
        (
            "parameters/vehicle.M_v",
            {"dist": "uniform", "low": 1.0, "high": 2.0, "mode": 1},
            "vehicle.M_v'.mode",
        ),
        ("parameters/vehicle.M_v", {"dist": "uniform", "low": -5.0, "high": 1.0}, "vehicle.M_v"),
        (
            "parameters/actuator.omega_a",
            {"dist": "loguniform", "low": 0.0, "high": 1.0},
            "omega_a'.low",
        ),
        ("parameters/controller.k_r", {"dist": "uniform", "low": 1e-4, "high": 5e-4}, "'pi'"),
        ("parameters/controller.nonsense", {"values": [1.0]}, "controller.nonsense"),
        ("sampling/samples", 0, "sampling.samples"),
        ("sampling/samples", None, "sampling.samples"),
        ("sampling/method", "halton", "sampling.method"),
        ("sampling/seed", -1, "sampling.seed"),
        ("sampling/extra", 1, "sampling.extra"),
        ("study/criteria", ["lockup_tme_s <= 3.0"], "study.criteria[0]"),
        ("study/criteria", ["lockup_time_s <== 3.0"], "study.criteria[0]"),
        ("study/criteria", ["lockup_time_s <= __import__('os')"], "study.criteria[0]"),
        ("study/metrics", ["jerk"], "study.metrics[0]"),
        ("study/controllers", ["paper", "nope"], "study.controllers[1]"),
        ("study/scenarios", ["engage-ramp"], "study.scenarios[0]"),
        ("study/model", "half", "study.model"),
        ("study/t_end", -1.0, "study.t_end"),
        ("study/colour", "red", "study.colour"),
    ],
)
def test_every_bad_input_is_rejected_naming_the_key(path: str, value: Any, named: str) -> None:
    with pytest.raises(StudyError) as err:
        Study.from_dict(_with(path, value))
    assert named in str(err.value), str(err.value)


def test_a_grid_needs_values_and_no_other_count() -> None:
    with pytest.raises(StudyError, match="parameters.'vehicle.M_v'.dist"):
        Study.from_dict(_with("sampling/method", "grid", _with("sampling/samples", None)))
    d = _base()
    d["sampling"] = {"method": "grid", "samples": 5}
    d["parameters"] = {"vehicle.M_v": {"values": [1200.0, 1300.0]}}
    with pytest.raises(StudyError, match="sampling.samples = 5"):
        Study.from_dict(d)


def test_a_study_file_error_names_the_file_and_the_key(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text(
        '[study]\nname = "x"\ncontrollers = ["paper"]\nscenarios = ["paper-start"]\n'
        '[sampling]\nmethod = "mc"\nsamples = 0\n'
    )
    with pytest.raises(StudyError, match=r"sampling.samples = 0.*s\.toml"):
        load_study(f)
    with pytest.raises(StudyError, match="not found"):
        load_study(tmp_path / "missing.toml")


def test_the_shipped_studies_load_with_their_sample_counts() -> None:
    mc = load_study(ROOT / "analyses" / "studies" / "paper_start_mc.toml")
    quick = load_study(ROOT / "analyses" / "studies" / "paper_start_quick.toml")
    assert mc.samples == 10_000 and quick.samples <= 200
    for s in (mc, quick):
        assert s.controller_names == ("paper", "pi") and s.scenario_names == ("paper-start",)
        assert {c.metric for c in s.criteria} <= set(s.metrics)
        assert "summary" not in s.summary() and str(s.samples) in s.summary()
    assert len(sample_table(quick)) == quick.samples
