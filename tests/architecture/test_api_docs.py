"""Every module of the package has its place in the API reference (docs/api.rst), so a new module
cannot be left out of the docs by accident."""

from __future__ import annotations

import re
from pathlib import Path

import drivetrain_ctrl

ROOT = Path(drivetrain_ctrl.__file__).parent


def test_every_module_is_in_the_api_reference() -> None:
    api = (ROOT.parent / "docs" / "api.rst").read_text(encoding="utf-8")
    documented = set(re.findall(r"^\.\. automodule:: ([\w.]+)", api, flags=re.M))
    modules = {
        ".".join(("drivetrain_ctrl", *p.relative_to(ROOT).with_suffix("").parts))
        for p in ROOT.rglob("*.py")
        if p.name != "__init__.py"
    }
    assert modules - documented == set(), sorted(modules - documented)
    assert documented - modules <= {
        f"drivetrain_ctrl.{p.parent.name}" for p in ROOT.glob("*/__init__.py")
    } | {"drivetrain_ctrl"}
