"""A study row's paired linear figures, loop gain, judder threshold and controller stability check
(issue 23 item 6) against values pinned from the implementation before the numpy fast paths
(python-control's interconnections, conversions and transfer-function feedback; commit 7485aa7):
six samples of the quick study (``analyses/studies/paper_start_quick.toml``) on both models,
under law (6), the PI and the sampled PI (whose loop keeps python-control's realisation). The
fast paths compute the same numbers by other arithmetic, so they agree to round-off: relative
``1e-7`` on the margins (the conversion of an 11-state loop to a transfer function loses a few
digits either way), ``1e-9`` on the judder bracket and the poles."""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import Any

import control
import numpy as np
import pytest

from drivetrain_ctrl.control.laws import _STABILITY_CACHE
from drivetrain_ctrl.linear import clutch as LC
from drivetrain_ctrl.linear.operating_point import (
    _reduction,
    _reduction_of,
    slip_point_after_start,
)
from drivetrain_ctrl.studies.case import Case, linear_figures, simulate_case

ROWS: list[dict[str, Any]] = [
    {
        "model": "full",
        "controller": "paper",
        "overrides": {
            "clutch.k12_max": 258.3339019304416,
            "clutch.static_ratio": 1.1736884484089156,
            "vehicle.M_v": 1275.4052090394505,
            "actuator.omega_a": 250.24513520047088,
        },
        "figures": {
            "lin:gain_margin": 77.8736412775305,
            "lin:phase_margin_deg": 89.78595200913014,
            "lin:disk_margin": 1.8776298694883748,
            "lin:Ms": 1.030076982561152,
            "lin:crossover_rad_s": 5.14369985365946,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.0013120825973100614,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [322287.0842990875],
        "L_den": [1.0, 400.5422163207549, 62682.68652395016, 9393.394153725338],
        "judder": [-0.0013120825973100614, -0.0013120140991321806, -0.0013121510954879423, 39],
        "judder_open": [
            -0.0002588520772426506,
            -0.0002588385467383778,
            -0.00025886560774692337,
            35,
        ],
        "stable": True,
        "poles": [
            [-197.8540828706718, -147.04956690679546],
            [-197.8540828706718, 147.04956690679546],
            [-4.834050579410276, 0.0],
        ],
    },
    {
        "model": "full",
        "controller": "pi",
        "overrides": {
            "clutch.k12_max": 258.3339019304416,
            "clutch.static_ratio": 1.1736884484089156,
            "vehicle.M_v": 1275.4052090394505,
            "actuator.omega_a": 250.24513520047088,
        },
        "figures": {
            "lin:gain_margin": 20.235084815519972,
            "lin:phase_margin_deg": 68.98469943869338,
            "lin:disk_margin": 1.3340633132159254,
            "lin:Ms": 1.119144607428896,
            "lin:crossover_rad_s": 19.743184575575114,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.0009155923110090224,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [1200677.3728628159, 6003386.864314025],
        "L_den": [1.0, 400.54221632075337, 62682.68652395036, 9393.394153725345, 0.0],
        "judder": [-0.0009155923110090224, -0.0009155009801051811, -0.0009156836419128637, 37],
        "judder_open": [
            -0.00018168761137495743,
            -0.00018166957070259372,
            -0.00018170565204732116,
            33,
        ],
        "stable": True,
        "poles": [
            [-192.0546225892759, -139.2890835369033],
            [-192.0546225892759, 139.2890835369033],
            [-8.216485571100698, -4.085694173386799],
            [-8.216485571100698, 4.085694173386799],
        ],
    },
    {
        "model": "full",
        "controller": "pi-10ms",
        "overrides": {
            "clutch.k12_max": 258.3339019304416,
            "clutch.static_ratio": 1.1736884484089156,
            "vehicle.M_v": 1275.4052090394505,
            "actuator.omega_a": 250.24513520047088,
        },
        "figures": {
            "lin:gain_margin": 3.9231010569609333,
            "lin:phase_margin_deg": 51.95943397143466,
            "lin:disk_margin": 0.9230816317086046,
            "lin:Ms": 1.499225690701205,
            "lin:crossover_rad_s": 19.272712913044277,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": None,
            "lin:judder_margin": None,
            "lin:stable": 1.0,
        },
        "L_num": [
            0.0750740839799029,
            -0.11441165105981867,
            -0.08864456798912405,
            0.21130980847227224,
            -0.07440635028798867,
            -0.008921323115523015,
        ],
        "L_den": [
            1.0,
            -4.016860995765655,
            6.087505429620798,
            -4.179559954603801,
            1.182257774815402,
            -0.09155242555108421,
            0.018210171486519232,
            0.0,
        ],
        "judder": [None, None, None, 1],
        "judder_open": [None, None, None, 1],
        "stable": True,
        "poles": [
            [-0.1175940321182398, -0.07383368000349676],
            [-0.1175940321182398, 0.07383368000349676],
            [0.44847754012349705, 0.0],
            [0.9019621327064642, -0.03625344784376806],
            [0.9019621327064642, 0.03625344784376806],
        ],
    },
    {
        "model": "full",
        "controller": "paper",
        "overrides": {
            "clutch.k12_max": 292.8057695791683,
            "clutch.static_ratio": 1.1837720641395408,
            "vehicle.M_v": 1330.9569434189652,
            "actuator.omega_a": 372.77742652355045,
        },
        "figures": {
            "lin:gain_margin": 115.95700669640443,
            "lin:phase_margin_deg": 90.40494287926299,
            "lin:disk_margin": 1.9161579779433136,
            "lin:Ms": 1.0204291706681667,
            "lin:crossover_rad_s": 5.14451554351383,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.0012241309369108908,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [715239.3340816498],
        "L_den": [1.0, 596.593882437684, 139052.4763078873, 20844.451458828236],
        "judder": [-0.0012241309369108908, -0.0012240624387330097, -0.0012241994350887717, 39],
        "judder_open": [
            -0.00024229074001276167,
            -0.00024227720950848887,
            -0.00024230427051703444,
            35,
        ],
        "stable": True,
        "poles": [
            [-295.5877479890288, -220.17525347775216],
            [-295.5877479890288, 220.17525347775216],
            [-5.418386459623265, 0.0],
        ],
    },
    {
        "model": "full",
        "controller": "pi",
        "overrides": {
            "clutch.k12_max": 292.8057695791683,
            "clutch.static_ratio": 1.1837720641395408,
            "vehicle.M_v": 1330.9569434189652,
            "actuator.omega_a": 372.77742652355045,
        },
        "figures": {
            "lin:gain_margin": 26.874354695973892,
            "lin:phase_margin_deg": 72.2468615722895,
            "lin:disk_margin": 1.4026830636107217,
            "lin:Ms": 1.0888564221569412,
            "lin:crossover_rad_s": 22.250761262154796,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.0008574601907140356,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [3019899.4105968475, 15099497.052985007],
        "L_den": [1.0, 596.5938824376796, 139052.47630788616, 20844.451458828105, 0.0],
        "judder": [-0.0008574601907140356, -0.000857414525262115, -0.0008575058561659562, 38],
        "judder_open": [
            -0.00017282062090819236,
            -0.0001728116005720105,
            -0.00017282964124437422,
            34,
        ],
        "stable": True,
        "poles": [
            [-289.1385656969884, -211.58058594743312],
            [-289.1385656969884, 211.58058594743312],
            [-9.15837552185214, -2.9979480491759305],
            [-9.15837552185214, 2.9979480491759305],
        ],
    },
    {
        "model": "full",
        "controller": "pi-10ms",
        "overrides": {
            "clutch.k12_max": 292.8057695791683,
            "clutch.static_ratio": 1.1837720641395408,
            "vehicle.M_v": 1330.9569434189652,
            "actuator.omega_a": 372.77742652355045,
        },
        "figures": {
            "lin:gain_margin": 4.319464915566775,
            "lin:phase_margin_deg": 32.619060511428216,
            "lin:disk_margin": 0.9809187090826582,
            "lin:Ms": 1.4397286227823833,
            "lin:crossover_rad_s": 0.25099161624649685,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": None,
            "lin:judder_margin": None,
            "lin:stable": 1.0,
        },
        "L_num": [
            0.1092874883579178,
            -0.22897974043212968,
            0.045709771738198415,
            0.15429764575535204,
            -0.07623958173555175,
            -0.00407558368351416,
        ],
        "L_den": [
            1.0,
            -3.9355477685269062,
            5.746712735099644,
            -3.6294148207650916,
            0.7634462773603768,
            0.05223980982157349,
            0.0025637670103326286,
            0.0,
        ],
        "judder": [None, None, None, 1],
        "judder_open": [None, None, None, 1],
        "stable": True,
        "poles": [
            [-0.21370291846558437, 0.0],
            [-0.050213838379989294, 0.0],
            [0.4267469478812983, 0.0],
            [0.8670322557015726, 0.0],
            [0.906024053265769, 0.0],
        ],
    },
    {
        "model": "reduced",
        "controller": "paper",
        "overrides": {
            "clutch.k12_max": 258.3339019304416,
            "clutch.static_ratio": 1.1736884484089156,
            "vehicle.M_v": 1275.4052090394505,
            "actuator.omega_a": 250.24513520047088,
        },
        "figures": {
            "lin:gain_margin": 77.87364127855155,
            "lin:phase_margin_deg": 89.78595200917675,
            "lin:disk_margin": 1.8776298694898967,
            "lin:Ms": 1.030076982560766,
            "lin:crossover_rad_s": 5.143699853591965,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.006885753371131552,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [322287.0842948607],
        "L_den": [1.0, 400.5422163207537, 62682.686523950084, 9393.3941537253],
        "judder": [-0.006872674773829082, -0.0068723280018035595, -0.0068730215458546046, 43],
        "judder_open": [
            -0.0002588520772426506,
            -0.0002588385467383778,
            -0.00025886560774692337,
            35,
        ],
        "stable": True,
        "poles": [
            [-197.8540828706718, -147.04956690679546],
            [-197.8540828706718, 147.04956690679546],
            [-4.834050579410276, 0.0],
        ],
    },
    {
        "model": "reduced",
        "controller": "pi",
        "overrides": {
            "clutch.k12_max": 258.3339019304416,
            "clutch.static_ratio": 1.1736884484089156,
            "vehicle.M_v": 1275.4052090394505,
            "actuator.omega_a": 250.24513520047088,
        },
        "figures": {
            "lin:gain_margin": 20.235084815513716,
            "lin:phase_margin_deg": 68.984699438695,
            "lin:disk_margin": 1.3340633132160031,
            "lin:Ms": 1.1191446074289322,
            "lin:crossover_rad_s": 19.74318457558089,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.005097423980027716,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [1200677.3728631856, 6003386.864315918],
        "L_den": [1.0, 400.54221632075394, 62682.68652395017, 9393.394153725316, 0.0],
        "judder": [-0.004967162493583318, -0.004966700130882622, -0.0049676248562840145, 41],
        "judder_open": [
            -0.00018168761137495743,
            -0.00018166957070259372,
            -0.00018170565204732116,
            33,
        ],
        "stable": True,
        "poles": [
            [-192.0546225892759, -139.2890835369033],
            [-192.0546225892759, 139.2890835369033],
            [-8.216485571100698, -4.085694173386799],
            [-8.216485571100698, 4.085694173386799],
        ],
    },
    {
        "model": "reduced",
        "controller": "pi-10ms",
        "overrides": {
            "clutch.k12_max": 258.3339019304416,
            "clutch.static_ratio": 1.1736884484089156,
            "vehicle.M_v": 1275.4052090394505,
            "actuator.omega_a": 250.24513520047088,
        },
        "figures": {
            "lin:gain_margin": 3.9230990555336263,
            "lin:phase_margin_deg": 51.959163331299436,
            "lin:disk_margin": 0.9232849717371081,
            "lin:Ms": 1.498809097506007,
            "lin:crossover_rad_s": 19.272703194550854,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.0038789918774939256,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [
            0.07507408397990645,
            0.035710028210214996,
            -0.09228470656626546,
            -0.008924471973312701,
        ],
        "L_den": [
            1.0,
            -2.0172147589488194,
            1.0541432885382422,
            -0.055145146482363946,
            0.01821661580407934,
            0.0,
        ],
        "judder": [-0.0038789918774939256, -0.003878760696143577, -0.003879223058844274, 42],
        "judder_open": [
            -0.00020510440410305745,
            -0.0002050863634306937,
            -0.00020512244477542116,
            33,
        ],
        "stable": True,
        "poles": [
            [-0.1175940321182398, -0.07383368000349676],
            [-0.1175940321182398, 0.07383368000349676],
            [0.44847754012349705, 0.0],
            [0.9019621327064642, -0.03625344784376806],
            [0.9019621327064642, 0.03625344784376806],
        ],
    },
    {
        "model": "reduced",
        "controller": "paper",
        "overrides": {
            "clutch.k12_max": 292.8057695791683,
            "clutch.static_ratio": 1.1837720641395408,
            "vehicle.M_v": 1330.9569434189652,
            "actuator.omega_a": 372.77742652355045,
        },
        "figures": {
            "lin:gain_margin": 115.95700669587691,
            "lin:phase_margin_deg": 90.40494287924969,
            "lin:disk_margin": 1.9161579779429447,
            "lin:Ms": 1.0204291706682571,
            "lin:crossover_rad_s": 5.144515543537224,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.006485923466625021,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [715239.3340848968],
        "L_den": [1.0, 596.593882437681, 139052.47630788668, 20844.45145882813],
        "judder": [-0.0064738869444782845, -0.006473540172452762, -0.006474233716503807, 43],
        "judder_open": [
            -0.00024229074001276167,
            -0.00024227720950848887,
            -0.00024230427051703444,
            35,
        ],
        "stable": True,
        "poles": [
            [-295.5877479890288, -220.17525347775216],
            [-295.5877479890288, 220.17525347775216],
            [-5.418386459623265, 0.0],
        ],
    },
    {
        "model": "reduced",
        "controller": "pi",
        "overrides": {
            "clutch.k12_max": 292.8057695791683,
            "clutch.static_ratio": 1.1837720641395408,
            "vehicle.M_v": 1330.9569434189652,
            "actuator.omega_a": 372.77742652355045,
        },
        "figures": {
            "lin:gain_margin": 26.87435469611789,
            "lin:phase_margin_deg": 72.24686157225756,
            "lin:disk_margin": 1.4026830636091991,
            "lin:Ms": 1.0888564221564887,
            "lin:crossover_rad_s": 22.250761262041276,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.005275507970990587,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [3019899.4105806835, 15099497.052903404],
        "L_den": [1.0, 596.5938824376806, 139052.47630788657, 20844.451458828156, 0.0],
        "judder": [-0.0051012476767853246, -0.005100785314084628, -0.005101710039486021, 41],
        "judder_open": [
            -0.00017280258023582865,
            -0.0001727935598996468,
            -0.0001728116005720105,
            34,
        ],
        "stable": True,
        "poles": [
            [-289.1385656969884, -211.58058594743312],
            [-289.1385656969884, 211.58058594743312],
            [-9.15837552185214, -2.9979480491759305],
            [-9.15837552185214, 2.9979480491759305],
        ],
    },
    {
        "model": "reduced",
        "controller": "pi-10ms",
        "overrides": {
            "clutch.k12_max": 292.8057695791683,
            "clutch.static_ratio": 1.1837720641395408,
            "vehicle.M_v": 1330.9569434189652,
            "actuator.omega_a": 372.77742652355045,
        },
        "figures": {
            "lin:gain_margin": 4.319464429586031,
            "lin:phase_margin_deg": 54.18011765572365,
            "lin:disk_margin": 0.9808991104355593,
            "lin:Ms": 1.4394845886491663,
            "lin:crossover_rad_s": 19.541499683338504,
            "lin:mu_slope": -0.0,
            "lin:mu_slope_crit": -0.0037948418659671484,
            "lin:judder_margin": 1.0,
            "lin:stable": 1.0,
        },
        "L_num": [
            0.10928748835793911,
            -0.010441781023700511,
            -0.0844207245838022,
            -0.004076964611978635,
        ],
        "L_den": [
            1.0,
            -1.93588674521127,
            0.8759344422608172,
            0.0573876663025194,
            0.002564636363390196,
            0.0,
        ],
        "judder": [-0.0037948418659671484, -0.0037946106846168002, -0.0037950730473174966, 42],
        "judder_open": [
            -0.00019038321545426735,
            -0.00019036517478190362,
            -0.00019040125612663106,
            33,
        ],
        "stable": True,
        "poles": [
            [-0.21370291846558437, 0.0],
            [-0.050213838379989294, 0.0],
            [0.4267469478812983, 0.0],
            [0.8670322557015726, 0.0],
            [0.906024053265769, 0.0],
        ],
    },
]


def _run(row: dict[str, Any]) -> Any:
    case = Case(
        scenario="paper-start",
        params="passenger-car",
        overrides=row["overrides"],
        model=row["model"],
        controller=row["controller"],
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return simulate_case(case)


def _ids(row: dict[str, Any]) -> str:
    return f"{row['model']}-{row['controller']}-{row['overrides']['vehicle.M_v']:.0f}kg"


@pytest.fixture(scope="module", params=ROWS, ids=_ids)
def row_run(request: Any) -> tuple[dict[str, Any], Any]:
    return request.param, _run(request.param)


def _close(got: float | None, want: float | None, rel: float) -> None:
    if want is None:
        assert got is None
    else:
        assert got is not None and got == pytest.approx(want, rel=rel, abs=0.0)


def test_linear_figures_equal_the_pinned_ones(row_run: tuple[dict[str, Any], Any]) -> None:
    row, run = row_run
    figs = linear_figures(run.result, run.drivetrain, run.controller, start=run.scenario.start_time)
    for k, want in row["figures"].items():
        _close(figs[k], want, 1e-7)


def test_loop_gain_and_judder_threshold_equal_the_pinned_ones(
    row_run: tuple[dict[str, Any], Any],
) -> None:
    row, run = row_run
    op = slip_point_after_start(run.result, run.drivetrain, run.scenario.start_time)
    _es, L = LC.clutch_loop_gain(op, run.controller)
    for got, want in ((L.num[0][0], row["L_num"]), (L.den[0][0], row["L_den"])):
        got = np.asarray(got, dtype=float)
        assert got.shape == (len(want),)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-7 * float(np.max(np.abs(want))))
    for ctrl, want in ((run.controller, row["judder"]), (None, row["judder_open"])):
        jc = LC.judder_crossing(op, ctrl, rtol=1e-4)
        for g, w in zip((jc.mu_slope_crit, jc.stable_side, jc.unstable_side), want, strict=False):
            _close(g, w, 1e-9)
        assert jc.evaluations == want[3]


def test_stability_check_equals_the_pinned_poles(row_run: tuple[dict[str, Any], Any]) -> None:
    row, run = row_run
    _STABILITY_CACHE.clear()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        stable, poles = run.spec.check_stability(run.drivetrain.params)
    assert stable is row["stable"]
    got = sorted(poles, key=lambda p: (p.real, p.imag))
    want = [complex(*p) for p in row["poles"]]
    assert len(got) == len(want)
    scale = max(abs(p) for p in want)
    for g, w in zip(got, want, strict=True):
        assert abs(g - w) <= 1e-9 * scale


def test_error_chain_arrays_have_python_controls_transfer_function() -> None:
    """The numpy error chain (sign, rate limiter, actuator) of the continuous loop against the
    python-control realisation it replaced, on a frequency grid."""
    run = _run(ROWS[0])
    ctrl = run.controller
    op = slip_point_after_start(run.result, run.drivetrain, run.scenario.start_time)
    for c in (ctrl, dataclasses.replace(ctrl, rate_limit=(0.05, 2000.0))):
        fast = control.ss(*LC._error_chain_arrays(c, op))
        ref = LC._error_chain(c, op)
        w = np.logspace(-1, 5, 61)
        np.testing.assert_allclose(fast(1j * w), ref(1j * w), rtol=1e-12, atol=0.0)
        assert fast.nstates == ref.nstates


def test_the_kept_reduction_is_the_computed_one() -> None:
    run = _run(ROWS[0])
    op = slip_point_after_start(run.result, run.drivetrain, run.scenario.start_time)
    for keep in (False, True):
        a = _reduction(op.model, op.mode, keep_positions=keep)
        assert _reduction(op.model, op.mode, keep_positions=keep) is a  # kept
        b = _reduction_of(op.model, op.mode, keep_positions=keep)
        assert a.names == b.names and a.speed_rows == b.speed_rows
        for x, y in ((a.T, b.T), (a.S, b.S), (a.Nsel, b.Nsel)):
            np.testing.assert_array_equal(x, y)
            assert not x.flags.writeable
    assert math.isfinite(float(np.sum(a.T)))
