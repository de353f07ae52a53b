"""The one conversion of results to JSON: numpy values to Python ones, NaN and
infinities to ``null`` (JSON has neither), paths to strings.

>>> import numpy as np
>>> to_jsonable({"theta": np.array([1e-3, np.nan]), "n": np.int64(3), "ok": np.bool_(True)})
{'theta': [0.001, None], 'n': 3, 'ok': True}
>>> dumps({"max": float("inf")})
'{"max": null}'
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np


def to_jsonable(value: Any) -> Any:
    """``value`` with every numpy array, numpy scalar, tuple and path turned into plain
    JSON types, recursively; non-finite floats become None."""
    if isinstance(value, Mapping):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, list | tuple):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return value


def dumps(value: Any, **kwargs: Any) -> str:
    """``json.dumps`` of :func:`to_jsonable` (``value``); strict JSON (no NaN)."""
    return json.dumps(to_jsonable(value), allow_nan=False, **kwargs)
