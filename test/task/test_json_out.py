"""json_out: what `--json`, summary.json and evaluation.json write is JSON every parser reads (a
review found bare NaN: a slope without a success, a loss before the first update)."""
import json
import math

import numpy as np
import pytest

from lhd_loading_ros.task.json_out import dumps, jsonable


def test_non_finite_numbers_become_null_and_numpy_becomes_python():
    o = {"loaded_ok": [math.nan, 31.5], "q": np.float32(np.inf), "n": np.int64(3), "ok": np.bool_(True),
         "arr": np.array([1.0, np.nan]), "nested": ({"x": -math.inf},), "s": "nan"}
    text = dumps(o)
    back = json.loads(text, parse_constant=lambda c: pytest.fail(f"bare {c} in {text}"))
    assert back == {"loaded_ok": [None, 31.5], "q": None, "n": 3, "ok": True, "arr": [1.0, None],
                    "nested": [{"x": None}], "s": "nan"}
    assert jsonable({"series": [1], "a": 1}, drop_keys=("series",)) == {"a": 1}


def test_anything_else_not_json_is_refused():
    with pytest.raises(TypeError):
        dumps({"p": object()})
