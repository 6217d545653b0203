"""The shared TOML loader (:mod:`drivetrain_ctrl.loading`) as the controller and scenario loaders
use it: a file that cannot be read raises the loader's own error naming the file."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from drivetrain_ctrl.control.laws import ControllerError, load_controller
from drivetrain_ctrl.scenarios.scenario import ScenarioError, load_scenario


@pytest.mark.parametrize(
    ("load", "error"),
    [(load_controller, ControllerError), (load_scenario, ScenarioError)],
    ids=["controller", "scenario"],
)
def test_unreadable_files_raise_the_loaders_error(
    load: Callable[[Any], Any], error: type[Exception], tmp_path: Path
) -> None:
    d = tmp_path / "d.toml"
    d.mkdir()
    with pytest.raises(error, match=r"d\.toml: cannot read the file"):
        load(str(d))
    latin = tmp_path / "latin.toml"
    latin.write_bytes('name = "caf\xe9"\n'.encode("latin-1"))
    with pytest.raises(error, match=r"latin\.toml: not a UTF-8 text file"):
        load(latin)
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n", encoding="utf-8")
    with pytest.raises(error, match=r"bad\.toml: invalid TOML"):
        load(bad)
