"""Loading a named item: a built-in by name, or a TOML file (parameter sets, scenarios, controllers).

Built-ins are TOML files shipped as package data (``control/builtin/``, ``scenarios/builtin/``),
found with :mod:`importlib.resources` so they load from an installed wheel as from the source tree.
"""

from __future__ import annotations

import importlib.resources
import tomllib
from collections.abc import Callable, Mapping, Sequence
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any, TypeVar

from .validate import did_you_mean

T = TypeVar("T")


def load_builtin_or_toml(
    source: str | Path,
    builtins: Mapping[str, T],
    from_dict: Callable[[dict[str, Any]], T],
    *,
    what: str,
    error: type[ValueError],
) -> T:
    """``builtins[source]`` if ``source`` names a built-in, else ``from_dict`` of the TOML file
    ``source``. Errors are ``error`` naming ``what`` (e.g. "scenario"), with a did-you-mean hint
    for a misspelt built-in name and the file name for a bad file."""
    if isinstance(source, str) and source in builtins:
        return builtins[source]
    p = Path(source)
    if p.suffix != ".toml" or not p.exists():
        hint = did_you_mean(str(source), sorted(builtins))
        raise error(
            f"{what} {str(source)!r}: not a built-in {what} ({sorted(builtins)}) "
            f"nor an existing .toml file{hint}"
        )
    return load_toml_as(p, from_dict, error=error)


def builtin_files(
    package: str, folder: str = "builtin", *, order: Sequence[str] = ()
) -> dict[str, Traversable]:
    """The ``*.toml`` files in ``folder`` of ``package`` (package data), by file stem: first the
    names in ``order`` that exist (the order the built-ins are listed and run in), then the
    others alphabetically."""
    root = importlib.resources.files(package).joinpath(folder)
    found = {
        f.name.removesuffix(".toml"): f
        for f in root.iterdir()
        if f.name.endswith(".toml") and f.is_file()
    }
    names = [n for n in order if n in found] + sorted(set(found) - set(order))
    return {n: found[n] for n in names}


def read_toml(path: Path | Traversable, *, error: type[ValueError]) -> dict[str, Any]:
    """The table of the TOML file ``path``; an unreadable file (a directory, no permission, not
    UTF-8) and invalid TOML are raised as ``error`` with the file name. A missing file raises
    :class:`FileNotFoundError`."""
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: invalid TOML: {exc}") from None
    except FileNotFoundError:
        raise
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not a UTF-8 text file: {exc}") from None
    except OSError as exc:
        raise error(f"{path}: cannot read the file: {exc.strerror or exc}") from None


def load_toml_as(
    path: Path | Traversable, from_dict: Callable[[dict[str, Any]], T], *, error: type[ValueError]
) -> T:
    """``from_dict`` of the TOML file ``path``; an unreadable file (a directory, no permission,
    not UTF-8), invalid TOML and errors of ``from_dict`` are raised as ``error`` with the file
    name. A missing file raises :class:`FileNotFoundError` (callers report it)."""
    d = read_toml(path, error=error)
    try:
        return from_dict(d)
    except error as exc:
        raise error(f"{exc} (in {path})") from None
