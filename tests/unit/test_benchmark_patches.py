"""The benchmark scripts that patch a copy of the kernel (``profile_kernel.py``,
``step_control_check.py``) still match the kernel: they are run by hand, and a patch that no
longer applies would only be found then."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]
KERNELS = ROOT / "drivetrain_ctrl" / "kernels.py"


Bench = Callable[[str], ModuleType]


def test_profile_patches_apply(bench: Bench) -> None:
    pk = bench("profile_kernel")
    out = pk.apply_patches(KERNELS.read_text(), pk._PATCHES)
    assert out.count("rdtsc()") >= 10
    assert "        n_incons,\n        prof,\n    )" in out


@pytest.mark.parametrize("factor", [2.5, 2.0])
def test_step_control_patches_apply(bench: Bench, factor: float) -> None:
    sc = bench("step_control_check")
    out = bench("profile_kernel").apply_patches(KERNELS.read_text(), sc.variant_patches(factor))
    assert f"\nSTABILITY_FACTOR = {factor!r}\n" in out
    assert "ist[8 + imx] += 1" in out
    assert "        ist[8:].copy(),\n    )" in out


def test_apply_patches_names_a_stale_patch(bench: Bench) -> None:
    pk = bench("profile_kernel")
    with pytest.raises(SystemExit, match="patch 'gone'.*found 0"):
        pk.apply_patches("x = 1\n", [("gone", "y = 2\n", "y = 3\n", 1)])
