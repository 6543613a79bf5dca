"""Writes a script's results as strict JSON: NaN and infinities (a figure that does not exist) become null."""

import json
import math
from pathlib import Path


def _finite_or_none(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _finite_or_none(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_none(item) for item in value]
    return value


def write_json(path: Path, results: dict) -> None:
    path.write_text(json.dumps(_finite_or_none(results), indent=2, allow_nan=False))
    print(f"wrote {path}")
