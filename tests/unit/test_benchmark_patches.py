"""The benchmark scripts that patch a copy of the kernel (``profile_kernel.py``,
``step_control_check.py``) still match the kernel: they are run by hand, and a patch that no
longer applies would only be found then."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]
KERNELS = ROOT / "drivetrain_ctrl" / "kernels.py"


def _bench(name: str) -> ModuleType:
    path = str(ROOT / "benchmarks")
    if path not in sys.path:
        sys.path.insert(0, path)
    return importlib.import_module(name)


def test_profile_patches_apply() -> None:
    pk = _bench("profile_kernel")
    out = pk.apply_patches(KERNELS.read_text(), pk._PATCHES)
    assert out.count("rdtsc()") >= 10
    assert "        n_incons,\n        prof,\n    )" in out


@pytest.mark.parametrize("factor", [2.5, 2.0])
def test_step_control_patches_apply(factor: float) -> None:
    sc = _bench("step_control_check")
    out = _bench("profile_kernel").apply_patches(KERNELS.read_text(), sc.variant_patches(factor))
    assert f"\nSTABILITY_FACTOR = {factor!r}\n" in out
    assert "ist[8 + imx] += 1" in out
    assert "        ist[8:].copy(),\n    )" in out


def test_apply_patches_names_a_stale_patch() -> None:
    pk = _bench("profile_kernel")
    with pytest.raises(SystemExit, match="patch 'gone'.*found 0"):
        pk.apply_patches("x = 1\n", [("gone", "y = 2\n", "y = 3\n", 1)])
