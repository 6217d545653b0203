"""The distribution is honest about what it needs and what it names: every dependency declared
in ``pyproject.toml`` is imported by the package (and every third-party import is declared), and
no file in the package, source or data, names a path outside the repository."""

from __future__ import annotations

import ast
import re
import sys
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "drivetrain_ctrl"

#: declared dependencies not imported yet, with the reason they are declared (an entry must go
#: once the package imports the module; the test checks that too)
NOT_YET_IMPORTED: dict[str, str] = {}

#: import names of distributions whose module is named otherwise
IMPORT_NAME = {"tomli-w": "tomli_w", "salib": "SALib"}


def _declared() -> dict[str, str]:
    """Declared dependencies: distribution name -> top-level module name."""
    with (REPO / "pyproject.toml").open("rb") as fh:
        deps = tomllib.load(fh)["project"]["dependencies"]
    out = {}
    for d in deps:
        m = re.match(r"\s*([A-Za-z0-9_.-]+)", d)
        assert m, d
        name = m.group(1).lower()
        out[name] = IMPORT_NAME.get(name, name.replace("-", "_"))
    return out


def _imported() -> dict[str, set[str]]:
    """Absolute top-level modules imported anywhere in the package -> the files importing them."""
    found: dict[str, set[str]] = {}
    for f in PACKAGE.rglob("*.py"):
        tree = ast.parse(f.read_text(encoding="utf-8"), filename=str(f))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                mods = [node.module]
            else:
                continue
            for mod in mods:
                found.setdefault(mod.partition(".")[0], set()).add(str(f.relative_to(REPO)))
    return found


def test_every_declared_dependency_is_imported() -> None:
    imported = _imported()
    unused = {d for d, mod in _declared().items() if mod not in imported}
    assert unused == set(NOT_YET_IMPORTED), (
        f"declared but not imported: {sorted(unused - set(NOT_YET_IMPORTED))}; "
        f"listed as not yet imported but imported now (remove from NOT_YET_IMPORTED): "
        f"{sorted(set(NOT_YET_IMPORTED) - unused)}"
    )


def test_every_third_party_import_is_declared() -> None:
    declared = set(_declared().values())
    third_party = {
        mod: files
        for mod, files in _imported().items()
        if mod not in sys.stdlib_module_names and mod != "drivetrain_ctrl"
    }
    undeclared = {m: sorted(f) for m, f in third_party.items() if m not in declared}
    assert not undeclared, f"imported but not declared in pyproject's dependencies: {undeclared}"


#: what names a place outside the repository: absolute paths of this workplace or a home
#: folder, a path that climbs out of a folder, a temporary folder
OUTSIDE = re.compile(r"/work/|(?<![\w.])\.\./|/home/|/Users/|/root/|/tmp/|~/|\bshared/reference\b")

#: compiled artefacts beside the sources (numba's cache, bytecode): not source or data
_SKIP_SUFFIXES = {".pyc", ".pyo", ".nbi", ".nbc"}


def test_no_package_file_names_a_path_outside_the_repository() -> None:
    hits = []
    checked = 0
    for f in sorted(PACKAGE.rglob("*")):
        if not f.is_file() or "__pycache__" in f.parts or f.suffix in _SKIP_SUFFIXES:
            continue
        text = f.read_text(encoding="utf-8")
        checked += 1
        for i, line in enumerate(text.splitlines(), 1):
            if OUTSIDE.search(line):
                hits.append(f"{f.relative_to(REPO)}:{i}: {line.strip()}")
    assert checked > 20  # the walk saw the package
    assert not hits, "files naming a path outside the repository:\n" + "\n".join(hits)


def test_the_path_pattern_catches_what_it_should() -> None:
    for bad in (
        "# after /work/shared/reference/default_parameters.md",
        "see ../shared/notes.md",
        'Path("/home/me/data.toml")',
    ):
        assert OUTSIDE.search(bad), bad
    for fine in ("x = a/b", "relative: control/builtin/paper.toml", "1.../2", "omega_1 / tau_r"):
        assert not OUTSIDE.search(fine), fine
