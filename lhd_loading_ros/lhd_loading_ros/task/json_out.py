"""JSON that every parser reads: a value that is not a finite number (a mean over no successful
attempt, a loss before the first update) is written as null, never as the bare NaN / Infinity
that Python's json module writes by default and strict parsers (JSON.parse, jq, json.load with
parse_constant) refuse. numpy scalars become Python numbers. Pure; no ROS."""
from __future__ import annotations

import json
import math


def jsonable(o, drop_keys: tuple = ()):
    """`o` with every non-finite float as None (and numpy scalars and arrays as Python values);
    mapping keys in `drop_keys` are left out."""
    if isinstance(o, dict):
        return {k: jsonable(v, drop_keys) for k, v in o.items() if k not in drop_keys}
    if isinstance(o, (list, tuple)):
        return [jsonable(v, drop_keys) for v in o]
    if hasattr(o, "tolist") and hasattr(o, "dtype"):          # numpy scalar or array
        return jsonable(o.tolist(), drop_keys)
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    return o


def dumps(o, **kw) -> str:
    """json.dumps of jsonable(o), refusing anything still not JSON (allow_nan=False)."""
    return json.dumps(jsonable(o), allow_nan=False, **kw)
