"""The built distribution carries its data: a wheel built from the source tree holds every
parameter set, built-in controller and built-in scenario (TOML package data), and the package
installed from it finds them with :mod:`importlib.resources`, away from the source tree.

The wheel is built from a copy of the sources (setuptools writes ``build/`` and ``*.egg-info``
beside ``pyproject.toml``), with ``pip wheel --no-build-isolation`` when the environment's
setuptools meets ``[build-system] requires``, else in pip's isolated build environment (which
fetches the build backend from the package index, as ``./dev``'s editable install does).
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "drivetrain_ctrl"

#: folders of package data (relative to the package) and the package whose resources they are
DATA = {
    "plant/parameter_sets": "drivetrain_ctrl.plant",
    "control/builtin": "drivetrain_ctrl.control",
    "scenarios/builtin": "drivetrain_ctrl.scenarios",
    "design/specs": "drivetrain_ctrl.design",
}


def _data_files() -> dict[str, list[str]]:
    """The TOML files of each data folder in the source tree (names)."""
    return {d: sorted(p.name for p in (PACKAGE / d).glob("*.toml")) for d in DATA}


def _version_tuple(v: str) -> tuple[int, ...]:
    return tuple(int(x) for x in re.findall(r"\d+", v)[:3])


def _build_requirements_installed() -> bool:
    """True if every ``[build-system] requires`` entry (``name`` or ``name>=version``) is
    installed in this environment."""
    with (REPO / "pyproject.toml").open("rb") as fh:
        requires = tomllib.load(fh)["build-system"]["requires"]
    for req in requires:
        m = re.fullmatch(r"\s*([A-Za-z0-9_.-]+)\s*(?:>=\s*([0-9.]+))?\s*", req)
        if m is None:
            return False
        try:
            have = importlib.metadata.version(m.group(1))
        except importlib.metadata.PackageNotFoundError:
            return False
        if m.group(2) and _version_tuple(have) < _version_tuple(m.group(2)):
            return False
    return True


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, src / name)
    shutil.copytree(
        PACKAGE, src / "drivetrain_ctrl", ignore=shutil.ignore_patterns("__pycache__", "*.py[co]")
    )
    out = tmp_path_factory.mktemp("dist")
    cmd = [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "--disable-pip-version-check"]
    if _build_requirements_installed():
        cmd.append("--no-build-isolation")
    cmd += ["-w", str(out), str(src)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"{' '.join(cmd)} failed:\n{r.stdout}\n{r.stderr}"
    (whl,) = out.glob("drivetrain_ctrl-*.whl")
    return whl


def test_the_source_tree_has_the_data() -> None:
    files = _data_files()
    assert "passenger-car.toml" in files["plant/parameter_sets"]
    assert {"paper.toml", "pi.toml"} <= set(files["control/builtin"])
    assert {"engage-ramp.toml", "tip-in.toml", "paper-start.toml"} <= set(
        files["scenarios/builtin"]
    )


def test_the_wheel_holds_every_parameter_set_controller_and_scenario(wheel: Path) -> None:
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
    for folder, files in _data_files().items():
        for f in files:
            assert f"drivetrain_ctrl/{folder}/{f}" in names, (
                f"{folder}/{f} missing from {wheel.name}"
            )


_PROBE = """
import importlib.resources, json, sys
import drivetrain_ctrl
from drivetrain_ctrl import builtin_controllers, builtin_scenarios, default_params
from drivetrain_ctrl.plant.params import available_parameter_sets
data = json.loads(sys.argv[1])
found = {
    folder: sorted(
        f.name
        for f in importlib.resources.files(pkg).joinpath(folder.split("/")[1]).iterdir()
        if f.name.endswith(".toml")
    )
    for folder, pkg in data.items()
}
print(json.dumps({
    "file": drivetrain_ctrl.__file__,
    "found": found,
    "controllers": sorted(builtin_controllers()),
    "scenarios": sorted(builtin_scenarios()),
    "parameter_sets": available_parameter_sets(),
    "default": default_params().name,
}))
"""


def test_the_installed_package_finds_its_data(wheel: Path, tmp_path: Path) -> None:
    target = tmp_path / "site"
    r = subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index"]
        + ["--disable-pip-version-check", "--target", str(target), str(wheel)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    env = {**os.environ, "PYTHONPATH": str(target), "PYTHONDONTWRITEBYTECODE": "1"}
    r = subprocess.run(
        [sys.executable, "-c", _PROBE, json.dumps(DATA)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert Path(got["file"]).resolve().is_relative_to(target.resolve()), got["file"]
    assert got["found"] == _data_files()
    stems = {d: sorted(f.removesuffix(".toml") for f in fs) for d, fs in _data_files().items()}
    assert got["controllers"] == stems["control/builtin"]
    assert got["scenarios"] == stems["scenarios/builtin"]
    assert got["parameter_sets"] == stems["plant/parameter_sets"]
    assert got["default"] == "passenger-car"
