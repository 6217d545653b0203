"""The cache guard of the compiled kernels (:mod:`drivetrain_ctrl.kernels._jit`): an edit of any
file of the kernels package invalidates every cached kernel.

Numba keys a function's on-disk cache on the function's own source file only, so a cached caller
keeps the machine code of a helper from another file after that file is edited (numba issue
#1833). A synthetic two-file package shows both: the stale value without the guard, the new one
with it."""

from __future__ import annotations

import os
import pkgutil
import subprocess
import sys
from pathlib import Path

import drivetrain_ctrl
from drivetrain_ctrl import kernels
from drivetrain_ctrl.kernels._jit import KernelCache, PackageStampLocator, package_source_stamp

HELPERS = """
from drivetrain_ctrl.kernels._jit import jit, jit_inline


@jit_inline
def inlined():
    return {inlined}


@jit
def called():
    return {called}
"""
GUARDED = """
from drivetrain_ctrl.kernels._jit import jit

from .a import called, inlined


@jit
def total():
    return inlined() + called()
"""
PLAIN = """
from numba import njit

from .a import called, inlined


@njit(cache=True)
def total():
    return inlined() + called()
"""
RUN = """
from synth.b_guarded import total as guarded
from synth.b_plain import total as plain
print(guarded(), plain())
"""


def _run(root: Path) -> tuple[list[float], str]:
    repo = str(Path(drivetrain_ctrl.__file__).resolve().parents[1])
    path = os.pathsep.join([str(root), repo, os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, "PYTHONPATH": path, "NUMBA_DEBUG_CACHE": "1"}
    out = subprocess.run(
        [sys.executable, "-c", RUN], env=env, capture_output=True, text=True, check=True
    )
    return [float(v) for v in out.stdout.strip().splitlines()[-1].split()], out.stdout


def test_an_edit_of_a_helper_file_recompiles_its_guarded_callers(tmp_path: Path) -> None:
    pkg = tmp_path / "synth"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text(HELPERS.format(inlined="1.0", called="10.0"))
    (pkg / "b_guarded.py").write_text(GUARDED)
    (pkg / "b_plain.py").write_text(PLAIN)
    assert _run(tmp_path)[0] == [11.0, 11.0]  # compiled and saved
    (pkg / "a.py").write_text(HELPERS.format(inlined="2.0", called="20.0"))
    # numba's own stamp (b_plain.py unchanged) loads the stale machine code; the guard's
    # package-wide stamp recompiles
    assert _run(tmp_path)[0] == [22.0, 11.0]
    # unchanged sources: the guarded function is loaded from the cache, not compiled
    values, log = _run(tmp_path)
    assert values == [22.0, 11.0]
    lines = [ln for ln in log.splitlines() if "b_guarded.total" in ln]
    assert any("data loaded from" in ln for ln in lines), log
    assert not any("data saved to" in ln for ln in lines), log


def test_the_package_stamp_changes_with_any_file(tmp_path: Path) -> None:
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "b.py").write_text("y = 2\n")
    (tmp_path / "notes.txt").write_text("not a source")
    s0 = package_source_stamp(str(tmp_path))
    (tmp_path / "notes.txt").write_text("still not a source")
    assert package_source_stamp(str(tmp_path)) == s0
    (tmp_path / "b.py").write_text("y = 3\n")  # same size, other content
    s1 = package_source_stamp(str(tmp_path))
    assert s1 != s0
    (tmp_path / "c.py").write_text("")
    assert package_source_stamp(str(tmp_path)) not in (s0, s1)


def test_every_kernel_uses_the_guard() -> None:
    from numba.core.dispatcher import Dispatcher

    root = str(Path(kernels.__file__).parent)
    stamp = package_source_stamp(root)
    seen = {}
    for info in pkgutil.iter_modules(kernels.__path__):
        mod = __import__(f"{kernels.__name__}.{info.name}", fromlist=["_"])
        for name, obj in vars(mod).items():
            if isinstance(obj, Dispatcher) and obj.py_func.__module__ == mod.__name__:
                seen[f"{info.name}.{name}"] = obj
    # every decorated function of the package, found by its decorator in the sources
    n_decorated = sum(
        ln.startswith("@jit") for f in Path(root).glob("*.py") for ln in f.read_text().splitlines()
    )
    assert len(seen) == n_decorated and "integrator.simulate_kernel" in seen, sorted(seen)
    for name, disp in seen.items():
        cache = disp._cache
        assert isinstance(cache, KernelCache), name
        locator = cache._impl.locator
        assert isinstance(locator, PackageStampLocator), name
        assert locator.get_source_stamp() == stamp, name
        assert cache._cache_file._source_stamp == stamp, name
