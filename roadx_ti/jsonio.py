"""Machine-readable output: strict JSON everywhere (RFC 8259: no NaN or Infinity).

Every JSON the CLI prints or writes goes through here: non-finite floats become ``null`` (a type II
error with no non-target point, kappa of an all-target cloud), numpy values become their Python
equivalents, paths strings, and ``json.dumps(allow_nan=False)`` guarantees that nothing else slips
through. ``jq`` and ``json.loads(..., parse_constant=...)`` read the result.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np


def clean(value):
    """``value`` with non-finite floats as None and numpy / Path values as plain JSON types."""
    if isinstance(value, dict):
        return {str(k): clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return clean(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    return value


def dumps(value, **kwargs) -> str:
    """Strict JSON text of ``value`` (see ``clean``); other types fall back to str."""
    return json.dumps(clean(value), allow_nan=False, default=str, **kwargs)


def write(path, data) -> None:
    """``data`` as indented strict JSON, written atomically."""
    from roadx_ti.io.atomic import atomic_output

    with atomic_output(path) as tmp:
        Path(tmp).write_text(dumps(data, indent=2) + "\n")
