"""Every analysis script runs in quick mode and produces its figures and numbers."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _load(name: str):  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(name, ROOT / "analyses" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_paper_fig14_quick(tmp_path: Path) -> None:
    res = _load("paper_fig14").main(quick=True, out=tmp_path)
    runs = res["paper"]["runs"]
    for kind in ("reduced", "full"):
        m = runs[kind]
        assert m["lockup_time_s"] is not None and 1.0 < m["lockup_time_s"] < 3.5
    assert all(res["paper"]["checks"].values()), res["paper"]["checks"]
    assert (tmp_path / "fig14_paper.png").stat().st_size > 20_000
    data = json.loads((tmp_path / "metrics.json").read_text())
    assert data["paper"]["runs"]["full"]["lockup_time_s"] == runs["full"]["lockup_time_s"]
