"""JSON-ready numbers: rounding to significant digits so that written files are byte-stable."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: significant digits kept for every float of :func:`engagement_metrics`
SIGNIFICANT_DIGITS: int = 9


def round_sig(value: float | None, digits: int = SIGNIFICANT_DIGITS) -> float | None:
    """``value`` rounded to ``digits`` significant digits; None for None, NaN or +-inf.

    ``-0.0`` becomes ``0.0`` so that the JSON text does not depend on the sign of a zero.
    """
    if value is None:
        return None
    v = float(value)
    if not math.isfinite(v):
        return None
    if v == 0.0:
        return 0.0
    return float(f"{v:.{digits}g}")


def json_ready(obj: Any, digits: int = SIGNIFICANT_DIGITS) -> Any:
    """``obj`` with NumPy scalars converted and every float rounded by :func:`round_sig`
    (recursively through dicts, lists and tuples; tuples become lists)."""
    if isinstance(obj, dict):
        return {str(k): json_ready(v, digits) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_ready(v, digits) for v in obj]
    if isinstance(obj, bool | np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        return round_sig(float(obj), digits)
    return obj
