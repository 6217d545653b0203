"""The statistics of the study report (studies.analysis): the first-order Sobol estimator from
given data against analytic indices, the Wilson interval against scipy, how far a run misses a
criterion, failure reasons with their numbers folded."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from drivetrain_ctrl.studies.analysis import (
    MIN_ROWS,
    _reason,
    _violation,
    first_order_index,
    wilson_interval,
)
from drivetrain_ctrl.studies.study import Criterion


def test_first_order_index_equals_the_analytic_one_of_a_linear_model() -> None:
    # y = a x1 + b x2 with x1, x2 independent uniform: S1 = a^2 / (a^2 + b^2), S2 = b^2 / (...)
    rng = np.random.default_rng(0)
    x1, x2, x3 = rng.random((3, 4000))
    y = 3.0 * x1 + 1.0 * x2
    assert first_order_index(x1, y) == pytest.approx(0.9, abs=0.03)
    assert first_order_index(x2, y) == pytest.approx(0.1, abs=0.03)
    assert first_order_index(x3, y) == pytest.approx(0.0, abs=0.02)  # no influence: about 0


def test_first_order_index_sees_a_non_monotone_effect_that_spearman_misses() -> None:
    rng = np.random.default_rng(1)
    x = rng.random(2000)
    y = (x - 0.5) ** 2  # all variance explained by x, rank correlation about 0
    assert first_order_index(x, y) > 0.97
    assert abs(stats.spearmanr(x, y).statistic) < 0.1


def test_first_order_index_bins_a_discrete_parameter_by_value() -> None:
    x = np.repeat([1.0, 2.0, 3.0], 20)
    y = np.repeat([0.0, 1.0, 0.0], 20)
    assert first_order_index(x, y) == pytest.approx(1.0)
    # the bias correction: a pure-noise output against a 3-valued parameter stays near 0
    noise = np.random.default_rng(2).standard_normal(60)
    assert first_order_index(x, noise) < 0.1


def test_first_order_index_is_nan_when_undefined() -> None:
    assert math.isnan(first_order_index(np.arange(MIN_ROWS - 1.0), np.arange(MIN_ROWS - 1.0)))
    assert math.isnan(first_order_index(np.arange(20.0), np.ones(20)))  # constant output
    assert math.isnan(first_order_index(np.ones(20), np.arange(20.0)))  # constant input


def test_wilson_interval_is_scipys_and_brackets_the_rate() -> None:
    for k, n in ((0, 10), (3, 10), (10, 10), (57, 200)):
        lo, hi = wilson_interval(k, n)
        ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
        assert (lo, hi) == (pytest.approx(ci.low), pytest.approx(ci.high))
        assert lo <= k / n <= hi
    assert all(math.isnan(v) for v in wilson_interval(0, 0))


def test_violation_is_relative_to_the_threshold_and_undefined_is_worst() -> None:
    assert _violation(Criterion("lockup_time_s", "<=", 2.0), 2.5) == pytest.approx(0.25)
    assert _violation(Criterion("lockup_time_s", "<=", 2.0), 1.5) == pytest.approx(-0.25)
    assert _violation(Criterion("engine_speed_min_rpm", ">=", 700.0), 630.0) == pytest.approx(0.1)
    assert _violation(Criterion("n_backlash_impacts", "<=", 0.0), 3.0) == pytest.approx(3.0)
    assert _violation(Criterion("lockup_time_s", "<=", 2.0), math.nan) == math.inf


def test_failure_reasons_fold_numbers() -> None:
    assert _reason("failed", "ZenoError: Zeno at t = 1.25 s (3 events)") == (
        "failed: ZenoError: Zeno at t = # s (# events)"
    )
    assert _reason("max_steps", None) == "max_steps"
    assert _reason("failed", float("nan")) == "failed"
    assert _reason("failed", "vehicle.M_v = -1.2e3: must be > 0") == (
        "failed: vehicle.M_v = #: must be > #"
    )
    assert _reason("failed", "clutch.k12_max = 12.5") == "failed: clutch.k12_max = #"
