"""Writing a benchmark script's results: one JSON file in the results directory."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def write_json(out_dir: Path, name: str, data: dict[str, Any]) -> Path:
    """Write ``data`` as ``out_dir / name`` (indented, keys sorted, final newline: stable diffs),
    creating the directory; print and return the path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / name
    path.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    print(f"wrote {path}")
    return path
