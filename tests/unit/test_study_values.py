"""Value tests of drivetrain_ctrl.studies.study (issue 22 item 4): every distribution's values at
given quantiles against the formulas and scipy written out here, the unit samples of every
method against numpy's and scipy's generators called directly, the grid against a product
written by hand, criteria against plain comparisons, the parsed study's defaults and
conversions, the row keys, the digest against hashlib, the summary's counts, and each check of
a study naming its key (``./dev mutate drivetrain_ctrl/studies/study.py``)."""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats
from scipy.stats import qmc

from drivetrain_ctrl.sim.metrics import METRICS
from drivetrain_ctrl.studies.study import (
    Criterion,
    Parameter,
    Study,
    StudyError,
    load_study,
    row_key,
    sample_table,
)

U = np.array([0.0, 0.1, 0.25, 0.5, 0.7, 0.99, 0.999999])


def _base(**sampling: Any) -> dict[str, Any]:
    return {
        "study": {"name": "v", "controllers": ["paper"], "scenarios": ["paper-start"]},
        "sampling": {"method": "mc", "samples": 5, "seed": 3, **sampling},
        "parameters": {},
    }


def _with(d: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    """A copy of ``d`` with the ``/``-separated key set (None: removed)."""
    d = copy.deepcopy(d)
    *head, last = path.split("/")
    node = d
    for k in head:
        node = node[k]
    if value is None:
        node.pop(last, None)
    else:
        node[last] = value
    return d


def _err(d: Any) -> str:
    with pytest.raises(StudyError) as e:
        Study.from_dict(d)
    return str(e.value)


# -- distributions ---------------------------------------------------------------------------------


def test_ppf_of_every_distribution_equals_the_formula() -> None:
    uni = Parameter("x", "uniform", {"low": 2.0, "high": 5.0})
    assert uni.ppf(U) == pytest.approx([2.0 + 3.0 * u for u in U], rel=1e-15)
    lu = Parameter("x", "loguniform", {"low": 10.0, "high": 1000.0})
    # log-uniform on [10, 1000]: 10 * 100^u
    assert lu.ppf(U) == pytest.approx([10.0 * 100.0**u for u in U], rel=1e-12)
    nrm = Parameter("x", "normal", {"mean": 3.0, "std": 0.5})
    u = U[1:]  # u = 0 is -inf
    # the normal quantile from the error function: mean + std sqrt(2) erfinv(2u - 1)
    from scipy.special import erfinv

    assert nrm.ppf(u) == pytest.approx(3.0 + 0.5 * math.sqrt(2.0) * erfinv(2 * u - 1), rel=1e-9)
    tn = Parameter("x", "truncnormal", {"mean": 1.0, "std": 2.0, "low": 0.5, "high": 4.0})
    # inverse of the truncated cdf: Phi^-1(Phi(a) + u (Phi(b) - Phi(a))) with a, b standardised
    pa, pb = stats.norm.cdf((0.5 - 1.0) / 2.0), stats.norm.cdf((4.0 - 1.0) / 2.0)
    want = 1.0 + 2.0 * stats.norm.ppf(pa + U * (pb - pa))
    assert tn.ppf(U) == pytest.approx(want, rel=1e-9)
    assert tn.ppf(U).min() >= 0.5 and tn.ppf(U).max() <= 4.0
    vals = Parameter("x", "values", {"values": (7.0, 8.0, 9.0)})
    # equal probability: [0, 1/3) -> 7, [1/3, 2/3) -> 8, [2/3, 1) -> 9
    got = vals.ppf(np.array([0.0, 0.3333, 0.3334, 0.6666, 0.6667, 0.999999, 1.0]))
    assert got.tolist() == [7.0, 7.0, 8.0, 8.0, 9.0, 9.0, 9.0]


def test_the_support_is_what_the_load_checks() -> None:
    assert Parameter("x", "uniform", {"low": 1.0, "high": 2.0}).support() == (1.0, 2.0)
    assert Parameter("x", "loguniform", {"low": 1.0, "high": 2.0}).support() == (1.0, 2.0)
    assert Parameter("x", "normal", {"mean": 3.0, "std": 1.0}).support() == (3.0,)
    t = Parameter("x", "truncnormal", {"mean": 1.5, "std": 1.0, "low": 1.0, "high": 2.0})
    assert t.support() == (1.0, 2.0)
    assert Parameter("x", "values", {"values": (4.0, 5.0)}).support() == (4.0, 5.0)


# -- criteria -------------------------------------------------------------------------------------


@pytest.mark.parametrize("op", ["<=", ">=", "<", ">", "==", "!="])
def test_a_criterion_checks_like_the_plain_comparison_and_nan_fails(op: str) -> None:
    v = [1.0, 2.0, 3.0, math.nan, math.inf]
    plain = {
        "<=": lambda x: x <= 2.0,
        ">=": lambda x: x >= 2.0,
        "<": lambda x: x < 2.0,
        ">": lambda x: x > 2.0,
        "==": lambda x: x == 2.0,
        "!=": lambda x: x != 2.0,
    }[op]
    want = [bool(plain(x)) and math.isfinite(x) for x in v]
    d = _with(_base(), "study/criteria", [f"lockup_time_s {op} 2"])
    c = Study.from_dict(d).criteria[0]
    assert (c.metric, c.op, c.threshold) == ("lockup_time_s", op, 2.0)
    assert c.check(v).tolist() == want
    assert c.text == f"lockup_time_s {op} 2"


def test_criteria_are_parsed_with_spaces_and_exponents_and_bad_ones_named() -> None:
    d = _with(_base(), "study/criteria", ["  jerk_max_m_s3<1.5e1 ", "engine_speed_min_rpm >= 700"])
    s = Study.from_dict(d)
    assert s.criteria == (
        Criterion("jerk_max_m_s3", "<", 15.0),
        Criterion("engine_speed_min_rpm", ">=", 700.0),
    )
    assert s.criteria[0].text == "jerk_max_m_s3 < 15"
    # the criteria's metrics are kept even when the metrics list leaves them out
    s = Study.from_dict(_with(d, "study/metrics", ["lockup_time_s"]))
    assert s.metrics == ("lockup_time_s", "jerk_max_m_s3", "engine_speed_min_rpm")
    for bad, named in [
        (3.0, "study.criteria[0] = 3.0: must be a string"),
        ("lockup_time_s <= abc", "threshold 'abc' is not a number"),
        ("lockup_time_s <= inf", "threshold 'inf' must be finite"),
        ("lockup_time_s <= nan", "threshold 'nan' must be finite"),
        ("status == 1", "metric 'status' is a text"),
        ("lockup_time <= 1", "unknown metric 'lockup_time'"),
        ("lockup_time_s => 1", "must read '<metric> <op> <number>'"),
    ]:
        assert named in _err(_with(_base(), "study/criteria", [bad]))
    assert "study.criteria = 'x': must be a list" in _err(_with(_base(), "study/criteria", "x"))


# -- parameters -----------------------------------------------------------------------------------


def test_parameter_tables_are_read_with_their_arguments() -> None:
    d = _with(_base(), "parameters", {
        "vehicle.M_v": {"values": [1200, 1300.5]},  # dist defaults to values
        "clutch.k12_max": {"dist": "truncnormal", "mean": 250, "std": 10, "low": 240, "high": 260},
        "actuator.omega_a": {"dist": "loguniform", "low": 100, "high": 400},
    })  # fmt: skip
    s = Study.from_dict(d)
    p = {q.name: q for q in s.parameters}
    assert p["vehicle.M_v"].dist == "values"
    assert p["vehicle.M_v"].args == {"values": (1200.0, 1300.5)}
    assert all(type(v) is float for v in p["vehicle.M_v"].args["values"])
    assert p["clutch.k12_max"].args == {"mean": 250.0, "std": 10.0, "low": 240.0, "high": 260.0}
    assert p["actuator.omega_a"].args == {"low": 100.0, "high": 400.0}


@pytest.mark.parametrize(
    ("table", "named"),
    [
        (1.0, "parameters.'vehicle.M_v' = 1.0: must be a table"),
        ({"low": 1.0, "high": 2.0}, "parameters.'vehicle.M_v'.dist = None"),
        ({"dist": "uniform", "low": 1000.0}, "dist = 'uniform' needs 'high'"),
        ({"dist": "values", "values": []}, ".values = []: must be a non-empty list"),
        ({"dist": "values", "values": 1200.0}, ".values = 1200.0: must be a non-empty list"),
        ({"values": [1200.0, 1300.0, 1200.0]}, "values repeat"),
        ({"values": [1200.0, math.nan]}, ".values[1] = nan: must be a finite number"),
        ({"dist": "uniform", "low": 1200.0, "high": "x"}, ".high = 'x': must be a finite number"),
        ({"dist": "uniform", "low": 1200.0, "high": 1200.0}, ".low = 1200.0: must be below high"),
        ({"dist": "normal", "mean": 1200.0, "std": -1.0}, ".std = -1.0: must be > 0"),
        ({"dist": "loguniform", "low": -1.0, "high": 2.0}, ".low = -1.0: must be > 0"),
        (
            {"dist": "truncnormal", "mean": 1000.0, "std": 50.0, "low": 1100.0, "high": 1500.0},
            ".mean = 1000.0: must lie within [low, high]",
        ),
        (
            {"dist": "truncnormal", "mean": 1600.0, "std": 50.0, "low": 1100.0, "high": 1500.0},
            ".mean = 1600.0: must lie within [low, high]",
        ),
    ],
)
def test_a_bad_parameter_table_is_named(table: Any, named: str) -> None:
    assert named in _err(_with(_base(), "parameters", {"vehicle.M_v": table}))


def test_a_truncated_normal_may_have_its_mean_on_a_bound() -> None:
    for mean in (1100.0, 1500.0):
        t = {"dist": "truncnormal", "mean": mean, "std": 50.0, "low": 1100.0, "high": 1500.0}
        s = Study.from_dict(_with(_base(), "parameters", {"vehicle.M_v": t}))
        assert s.parameters[0].args["mean"] == mean


def test_every_value_a_parameter_can_take_is_checked_against_its_owner() -> None:
    def named(prm: str, table: dict[str, Any]) -> str:
        return _err(_with(_base(), "parameters", {prm: table}))

    # the parameter set: an unknown name, a value it rejects (any of the support's values)
    assert "parameters.'vehicle.nope'" in named("vehicle.nope", {"values": [1.0]})
    assert "parameters.'vehicle.M_v' = -1.0: vehicle.M_v" in named(
        "vehicle.M_v", {"values": [1200.0, -1.0]}
    )
    assert "parameters.'vehicle.M_v' = -1.0" in named(
        "vehicle.M_v", {"dist": "normal", "mean": -1.0, "std": 1.0}
    )
    # a controller gain: unknown, not settable, missing on a controller, a value it rejects
    assert "unknown controller setting 'colour'" in named("controller.colour", {"values": [1.0]})
    for fixed in ("name", "law", "design"):
        msg = named(f"controller.{fixed}", {"values": [1.0]})
        assert f"the controller's {fixed} cannot be a study parameter" in msg
        assert "did you mean" not in msg
    assert "controller 'paper' (law 'paper') has no kp" in named("controller.kp", {"values": [1.0]})
    assert "parameters.'controller.k_r' = -1.0: controller 'paper'" in named(
        "controller.k_r", {"values": [3e-4, -1.0]}
    )
    # a scenario field: unknown, a value the scenario rejects
    assert "unknown scenario field 'colour'" in named("scenario.colour", {"values": [1.0]})
    assert "parameters.'scenario.slope' = 2.0: paper-start: slope" in named(
        "scenario.slope", {"dist": "uniform", "low": 0.0, "high": 2.0}
    )
    # accepted ones
    ok = {
        "controller.k_r": {"values": [2e-4, 4e-4]},
        "scenario.slope": {"dist": "uniform", "low": 0.0, "high": 0.1},
        "vehicle.M_v": {"dist": "uniform", "low": 1100.0, "high": 1500.0},
    }
    s = Study.from_dict(_with(_base(), "parameters", ok))
    assert [p.name for p in s.parameters] == list(ok)


# -- the study table --------------------------------------------------------------------------------


def test_defaults_and_conversions_of_a_parsed_study() -> None:
    s = Study.from_dict(_with(_base(), "sampling/seed", None))
    assert s.seed == 0 and s.model == "reduced" and s.linear is True
    assert s.t_end is None and s.rtol is None and s.description == ""
    assert s.metrics == tuple(k for k, v in METRICS.items() if v.kind == "figure")
    assert "lockup_time_s" in s.metrics and "status" not in s.metrics
    d = _base()
    d["study"].update(
        t_end=2, rtol=1e-7, linear=False, model="full", description="d", controllers="paper",
        metrics=["jerk_max_m_s3", "lockup_time_s", "jerk_max_m_s3"],
    )  # fmt: skip
    s = Study.from_dict(d)
    assert (s.t_end, s.rtol, s.linear, s.model, s.description) == (2.0, 1e-7, False, "full", "d")
    assert type(s.t_end) is float and s.controllers == ("paper",)
    assert s.metrics == ("jerk_max_m_s3", "lockup_time_s")  # repeats dropped, order kept


def test_the_defaults_of_a_study_built_in_python() -> None:
    from drivetrain_ctrl.plant.params import DEFAULT_SET

    s = Study(
        name="py",
        parameters=(),
        method="mc",
        samples=2,
        seed=0,
        controllers=("paper",),
        scenarios=("paper-start",),
    )
    assert (s.model, s.params, s.metrics, s.criteria) == ("reduced", DEFAULT_SET, (), ())
    assert (s.t_end, s.rtol, s.description, s.linear) == (None, None, "", True)
    assert s.case(0, {}, "paper", 0).linear is True


@pytest.mark.parametrize(
    ("path", "value", "named"),
    [
        ("study", 1, "study: the [study] table is missing"),
        ("sampling", None, "sampling: the [sampling] table is missing"),
        ("study/name", " ", "study.name = ' ': must be a non-empty string"),
        ("study/name", 3, "study.name = 3"),
        ("study/description", 3, "study.description = 3: must be a string"),
        ("study/model", "half", "study.model = 'half'"),
        ("study/controllers", [], "study.controllers = []: must be a non-empty list"),
        ("study/controllers", 3, "study.controllers = 3"),
        ("study/scenarios", None, "study.scenarios = None"),
        ("study/scenarios", [""], "study.scenarios[0] = '': must be a built-in name"),
        ("study/metrics", [], "study.metrics = []: must be a non-empty list"),
        ("study/metrics", "lockup_time_s", "study.metrics = 'lockup_time_s'"),
        ("study/metrics", ["lockup_time_s", "jerk"], "study.metrics[1] = 'jerk'"),
        ("study/linear", 1, "study.linear = 1: must be true or false"),
        ("study/t_end", 0.0, "study.t_end = 0.0: must be a finite number > 0"),
        ("study/t_end", math.inf, "study.t_end = inf"),
        ("study/rtol", -1e-6, "study.rtol = -1e-06"),
        ("study/rtol", "x", "study.rtol = 'x'"),
        ("sampling/seed", 1.5, "sampling.seed = 1.5"),
        ("sampling/seed", True, "sampling.seed = True"),
        ("sampling/samples", True, "sampling.samples = True"),
        ("sampling/samples", 2.0, "sampling.samples = 2.0"),
        ("sampling/method", None, "sampling.method = None"),
        ("parameters", [1], "parameters = [1]: must be a table"),
    ],
)
def test_a_bad_study_table_is_named(path: str, value: Any, named: str) -> None:
    assert named in _err(_with(_base(), path, value))


def test_a_study_needs_a_table() -> None:
    assert "study: a table is needed, got [1]" in _err([1])
    assert "colour: unknown key" in _err({**_base(), "colour": 1})


def test_the_smallest_accepted_values() -> None:
    s = Study.from_dict(_with(_base(seed=0), "sampling/samples", 1))
    assert (s.samples, s.seed) == (1, 0)
    s = Study.from_dict(_with(_base(), "study/t_end", 1e-9))
    assert s.t_end == 1e-9


def test_the_loaded_things_are_checked_and_named() -> None:
    def named(path: str, value: Any) -> str:
        return _err(_with(_base(), path, value))

    assert "study.controllers[1] = 'paper': a second controller named 'paper'" in named(
        "study/controllers", ["paper", "paper"]
    )
    assert "study.controllers[0] = 'nope.toml'" in named("study/controllers", ["nope.toml"])
    assert "study.controllers[0] = 'nope'" in named("study/controllers", ["nope"])
    assert "study.scenarios[1] = 'paper-start': 'paper-start' given twice" in named(
        "study/scenarios", ["paper-start", "paper-start"]
    )
    assert "study.scenarios[0] = 'tip-in': an open-loop scenario" in named(
        "study/scenarios", ["tip-in"]
    )
    assert "study.scenarios[0] = 'nope'" in named("study/scenarios", ["nope"])
    assert "study.params = 'nope.toml': file not found" in named("study/params", "nope.toml")
    assert "study.params = 'nope': unknown parameter set" in named("study/params", "nope")
    s = Study.from_dict(_with(_base(), "study/scenarios", ["paper-start", "hill-start"]))
    assert s.scenario_names == ("paper-start", "hill-start")
    s = Study.from_dict(_with(_base(), "study/controllers", ["pi", "paper"]))
    assert s.controller_names == ("pi", "paper")


def test_relative_files_are_taken_from_the_study_folder(tmp_path: Path) -> None:
    from drivetrain_ctrl.plant.params import DEFAULT_SET

    assert Study.from_dict(_base()).params == DEFAULT_SET
    d = _with(_base(), "study/params", "sub/p.toml")
    for base, want in ((None, Path("sub/p.toml")), (tmp_path, tmp_path / "sub" / "p.toml")):
        with pytest.raises(StudyError) as e:
            Study.from_dict(d, base=base)
        assert str(e.value) == f"study.params = {str(want)!r}: file not found"
    absolute = tmp_path / "abs.toml"
    with pytest.raises(StudyError) as e:
        Study.from_dict(_with(_base(), "study/params", str(absolute)), base=Path("/elsewhere"))
    assert str(e.value) == f"study.params = {str(absolute)!r}: file not found"
    # a controller file next to the study file, named relatively
    (tmp_path / "c.toml").write_text('name = "mine"\nlaw = "paper"\nk_r = 2e-4\n')
    s = Study.from_dict(_with(_base(), "study/controllers", ["c.toml"]), base=tmp_path)
    assert s.controllers == (tmp_path / "c.toml",) and s.controller_names == ("mine",)


def test_a_study_file_is_read_and_a_missing_one_named(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text(
        '[study]\nname = "x"\ncontrollers = ["paper"]\nscenarios = ["paper-start"]\n'
        'criteria = ["lockup_time_s <= 3"]\n[sampling]\nmethod = "grid"\n'
        '[parameters."vehicle.M_v"]\nvalues = [1200.0, 1300.0]\n'
        '[parameters."controller.k_r"]\nvalues = [2e-4, 3e-4, 4e-4]\n'
    )
    s = load_study(f)
    assert (s.name, s.samples, s.method) == ("x", 6, "grid")
    assert s.criteria == (Criterion("lockup_time_s", "<=", 3.0),)
    with pytest.raises(StudyError, match="study file '.*nope.toml': not found"):
        load_study(tmp_path / "nope.toml")
    f.write_text('[study]\nname = "x"\n')
    with pytest.raises(StudyError, match=r"study.controllers = None.*\(in .*s\.toml\)"):
        load_study(f)


# -- samples -------------------------------------------------------------------------------------


def _study(method: str, n: int, seed: int, params: dict[str, Any]) -> Study:
    d = _base(method=method, samples=n, seed=seed)
    if method == "grid":
        d["sampling"].pop("samples")
    d["parameters"] = params
    return Study.from_dict(d)


TWO = {
    "vehicle.M_v": {"dist": "uniform", "low": 1100.0, "high": 1500.0},
    "actuator.omega_a": {"dist": "loguniform", "low": 100.0, "high": 400.0},
}


def test_monte_carlo_samples_are_numpys_generator_through_the_quantiles() -> None:
    df = sample_table(_study("mc", 7, 11, TWO))
    u = np.random.default_rng(11).random((7, 2))
    assert df["vehicle.M_v"].to_numpy() == pytest.approx(1100.0 + 400.0 * u[:, 0], rel=1e-14)
    assert df["actuator.omega_a"].to_numpy() == pytest.approx(100.0 * 4.0 ** u[:, 1], rel=1e-12)
    assert df.index.name == "sample" and df.index.tolist() == list(range(7))
    assert list(df.columns) == list(TWO)


def test_latin_hypercube_and_sobol_samples_are_scipys() -> None:
    for method in ("lhs", "sobol"):
        df = sample_table(_study(method, 8, 5, TWO))
        if method == "lhs":
            u = qmc.LatinHypercube(d=2, seed=5).random(8)
        else:
            u = qmc.Sobol(d=2, scramble=True, seed=5).random(8)
        assert df["vehicle.M_v"].to_numpy() == pytest.approx(1100.0 + 400.0 * u[:, 0], rel=1e-14)
        assert df["actuator.omega_a"].to_numpy() == pytest.approx(100.0 * 4.0 ** u[:, 1])
    # a scrambled Sobol sequence is not the unscrambled one (whose first point is the origin)
    df = sample_table(_study("sobol", 8, 5, TWO))
    plain = qmc.Sobol(d=2, scramble=False).random(8)
    assert not np.allclose(df["vehicle.M_v"].to_numpy(), 1100.0 + 400.0 * plain[:, 0])


def test_a_single_parameter_is_drawn_like_several() -> None:
    one = {"vehicle.M_v": TWO["vehicle.M_v"]}
    for method in ("mc", "lhs", "sobol"):
        df = sample_table(_study(method, 8, 2, one))
        if method == "mc":
            u = np.random.default_rng(2).random((8, 1))
        elif method == "lhs":
            u = qmc.LatinHypercube(d=1, seed=2).random(8)
        else:
            u = qmc.Sobol(d=1, scramble=True, seed=2).random(8)
        assert df["vehicle.M_v"].to_numpy() == pytest.approx(1100.0 + 400.0 * u[:, 0], rel=1e-14)
        assert df["vehicle.M_v"].nunique() == 8


def test_a_study_without_parameters_has_empty_sample_rows() -> None:
    for method in ("mc", "lhs", "sobol"):
        df = sample_table(_study(method, 4, 1, {}))
        assert df.shape == (4, 0) and df.index.tolist() == [0, 1, 2, 3]


def test_a_grid_is_the_product_in_table_order_last_parameter_fastest() -> None:
    params = {
        "vehicle.M_v": {"values": [1200.0, 1300.0, 1400.0]},
        "controller.k_r": {"values": [2e-4, 4e-4]},
        "scenario.slope": {"values": [0.0, 0.05]},
    }
    s = _study("grid", 0, 0, params)
    df = sample_table(s)
    want = list(itertools.product([1200.0, 1300.0, 1400.0], [2e-4, 4e-4], [0.0, 0.05]))
    assert s.samples == 12
    assert [tuple(r) for r in df.to_numpy().tolist()] == want
    assert "sampling.samples = 11" in _err(
        _with(_with(_base(), "parameters", params), "sampling", {"method": "grid", "samples": 11})
    )
    d = _with(_base(), "parameters", params)
    d["sampling"] = {"method": "grid", "samples": 12}
    assert Study.from_dict(d).samples == 12


# -- what a study runs -----------------------------------------------------------------------------


def test_keys_cases_summary_and_digest() -> None:
    params = {
        "vehicle.M_v": {"values": [1200.0, 1300.0]},
        "controller.x_r0": {"values": [0.065, 0.07]},
        "scenario.slope": {"values": [0.0, 0.05]},
    }
    d = _with(_base(), "parameters", params)
    d["study"].update(controllers=["paper", "pi"], scenarios=["paper-start", "hill-start"])
    d["study"]["criteria"] = ["lockup_time_s <= 3"]
    d["sampling"] = {"method": "grid", "seed": 4}
    s = Study.from_dict(d)
    assert row_key(12, "pi", "hill-start") == "s000012|pi|hill-start"
    keys = s.keys()
    assert len(keys) == 8 * 2 * 2
    assert keys[:5] == [
        "s000000|paper|paper-start",
        "s000000|paper|hill-start",
        "s000000|pi|paper-start",
        "s000000|pi|hill-start",
        "s000001|paper|paper-start",
    ]
    vals = {"vehicle.M_v": 1300.0, "controller.x_r0": 0.065, "scenario.slope": 0.05}
    case = s.case(5, vals, "pi", 1)
    assert case.overrides == {"vehicle.M_v": 1300.0}
    assert case.scenario_overrides == {"slope": 0.05}
    assert case.controller.name == "pi" and case.controller.x_r0 == 0.065
    assert case.controller.kp == 1e-3  # the other gains as loaded
    assert case.scenario == "hill-start" and case.label == "s000005|pi|hill-start"
    assert case.params is s._params and case.params is not None
    assert case.linear is True and case.model == "reduced"
    plain = s.case(0, {"vehicle.M_v": 1200.0}, "paper", 0)
    assert plain.controller == s._specs["paper"] and plain.scenario_overrides == {}
    assert s.summary() == (
        "study 'v': 8 samples (grid, seed 4) of vehicle.M_v, controller.x_r0, scenario.slope x "
        "2 controller(s) x 2 scenario(s) on the reduced model = 32 runs, 1 criteria"
    )
    none = Study.from_dict(_base())
    assert none.summary() == (
        "study 'v': 5 samples (mc, seed 3) of no parameters x 1 controller(s) x 1 scenario(s) "
        "on the reduced model = 5 runs, 0 criteria"
    )
    td = s.to_dict()
    assert td["criteria"] == ["lockup_time_s <= 3"] and td["samples"] == 8
    assert td["parameters"]["vehicle.M_v"] == {"dist": "values", "values": (1200.0, 1300.0)}
    assert td["controller_specs"]["pi"]["kp"] == 1e-3
    assert td["controller_specs"]["pi"]["design"] is None
    order = ["vehicle.M_v", "controller.x_r0", "scenario.slope"]
    text = json.dumps({**td, "parameter_order": order}, sort_keys=True, default=str)
    assert s.digest == hashlib.sha256(text.encode()).hexdigest()
    # another seed, another study
    assert Study.from_dict(_with(d, "sampling/seed", 5)).digest != s.digest
    assert Study.from_dict(_with(d, "study/linear", False)).digest != s.digest


def test_the_digest_changes_when_the_parameter_order_changes_the_samples() -> None:
    d = _with(_base(method="lhs", samples=4, seed=1), "parameters", TWO)
    r = _with(d, "parameters", dict(reversed(list(TWO.items()))))
    a, b = Study.from_dict(d), Study.from_dict(r)
    ta, tb = sample_table(a), sample_table(b)[list(TWO)]
    assert not np.allclose(ta.to_numpy(), tb.to_numpy())  # other samples
    assert a.digest != b.digest
