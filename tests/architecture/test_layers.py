"""The package is layered: every import goes down (or stays inside its own sub-package) and no
module imports itself back through a circle. The checker is tested on a synthetic package first,
so a planted upward import is shown to fail."""

from __future__ import annotations

from pathlib import Path

import pytest

import drivetrain_ctrl

from .layers import import_edges, violations

#: lowest first; equal ranks are peers and may not import each other
LAYERS = {
    "core": 0,
    "kernels": 1,
    "plant": 2,
    "control": 3,
    "testing": 3,
    "scenarios": 4,
    "sim": 5,
    "linear": 5,
    "design": 6,
    "studies": 7,  # above design: a comparison or study checks designed controllers with it
    "reporting": 8,
    "cli": 9,
    "": 10,  # the package's __init__: the public API, re-exported
}


def _write(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return root / "pkg"


def _synthetic(tmp_path: Path, extra: dict[str, str]) -> list[str]:
    files = {
        "pkg/__init__.py": "from .high import api\n",
        "pkg/low/__init__.py": "",
        "pkg/low/a.py": "X = 1\n",
        "pkg/low/b.py": "from .a import X\n",
        "pkg/high/__init__.py": "from .api import api\n",
        "pkg/high/api.py": "from ..low.b import X\n\ndef api():\n    return X\n",
        **extra,
    }
    root = _write(tmp_path, files)
    return violations(root, {"low": 0, "high": 1, "": 2}, plot_layer="high")


def test_checker_accepts_a_clean_package(tmp_path: Path) -> None:
    assert _synthetic(tmp_path, {}) == []


def test_checker_finds_a_planted_upward_import(tmp_path: Path) -> None:
    found = _synthetic(
        tmp_path, {"pkg/low/a.py": "X = 1\n\ndef f():\n    from ..high.api import api\n"}
    )
    assert any("pkg.low.a:4 imports pkg.high.api (low may not import high)" in v for v in found), (
        found
    )


def test_checker_finds_a_circle_inside_a_layer(tmp_path: Path) -> None:
    found = _synthetic(tmp_path, {"pkg/low/a.py": "import pkg.low.b\nX = 1\n"})
    assert "import circle: pkg.low.a -> pkg.low.b -> pkg.low.a" in found, found


def test_checker_allows_only_plot_methods_to_reach_the_plot_layer(tmp_path: Path) -> None:
    lazy = "class R:\n    def plot(self):\n        from ..high.api import api\n"
    assert _synthetic(tmp_path, {"pkg/low/c.py": lazy}) == []
    other = "class R:\n    def show(self):\n        from ..high.api import api\n"
    assert _synthetic(tmp_path, {"pkg/low/c.py": other}) != []


def test_checker_resolves_relative_and_module_imports(tmp_path: Path) -> None:
    root = _write(
        tmp_path,
        {"pkg/__init__.py": "", "pkg/low/__init__.py": "from . import a\n", "pkg/low/a.py": ""},
    )
    edges = {(e.src, e.dst) for e in import_edges(root)}
    assert ("pkg.low", "pkg.low.a") in edges


def test_drivetrain_ctrl_is_layered() -> None:
    root = Path(drivetrain_ctrl.__file__).parent
    found = violations(root, LAYERS, plot_layer="reporting")
    assert found == [], "\n".join(found)


def test_every_sub_package_has_a_layer() -> None:
    root = Path(drivetrain_ctrl.__file__).parent
    subs = {p.parent.name for p in root.glob("*/__init__.py")} | {
        p.stem for p in root.glob("*.py") if p.stem != "__init__"
    }
    assert subs <= set(LAYERS), sorted(subs - set(LAYERS))


@pytest.mark.parametrize("name", ["simulate", "default_params", "load_scenario", "run_scenario"])
def test_public_api_is_flat(name: str) -> None:
    assert name in drivetrain_ctrl.__all__ and callable(getattr(drivetrain_ctrl, name))
