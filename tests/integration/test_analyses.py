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


def test_paper_start_quick(tmp_path: Path) -> None:
    res = _load("paper_start").main(quick=True, out=tmp_path)
    m = res["reduced"]
    # law (6) keeps the engine alive and the clutch locks within the run
    assert m["lockup_time_s"] is not None and 1.0 < m["lockup_time_s"] < 3.5
    assert m["min_engine_speed_rpm"] > 400.0
    assert (tmp_path / "reduced.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "metrics.json").read_text())["reduced"] == m
