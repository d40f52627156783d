"""The bucket's fill against what loaders deliver (docs/modeling.md "Bucket capacity", open finding 10): the
Tampier-style heuristic curls until the bucket is full, so the volume in its bucket at the end is what the
simulator's kernel keeps. On the config (task.bucket_fill_factor 0.875) that must lie in the wheel-loader fill
factors of the Caterpillar Performance Handbook (ed. 47, Tables p. 30-2: 85-90 % of the SAE heaped rating for
uniform aggregates of 12 mm and over), written here, over the rating computed here by hand; on the static heap
(no fill factor, every actor before 2026-12-02) it over-fills, as the finding says. An end-to-end check that the
kernel keeps the fill the config names, on a maneuver; the handbook is the reference for that parameter."""
import copy
import math

import pytest

from lhd_sim_node.validate import heuristic_fill

HANDBOOK = (0.85, 0.90)
# the rating by hand: struck prism (plate 0.295 m, back 0.26 m, inner width 0.39 m) plus the SAE 2:1 hip roof
# over the strike plane A = hypot(0.295, 0.26) m long, A <= W: tan(t) A^2 (3 W - A) / 12 with tan(t) = 1/2
_A = math.hypot(0.295, 0.26)
SAE_L = (0.5 * 0.295 * 0.26 * 0.39 + 0.5 * _A * _A * (3 * 0.39 - _A) / 12.0) * 1e3


@pytest.fixture(scope="module")
def cfg():
    from lhd_loading_ros.task.config import load_config
    return load_config()


def _fills(res):
    return [a["loaded_L"] / SAE_L for a in res["attempts"] if a["curled"]]


def test_the_heuristic_delivers_the_handbook_fill(cfg):
    assert SAE_L == pytest.approx(19.96, abs=0.01)
    assert cfg["task"]["bucket_fill_factor"] == pytest.approx(0.875)
    res = heuristic_fill(cfg, slopes=(20.0, 25.0, 30.0), seeds=(0, 1))
    assert res["heaped_iso_L"] == pytest.approx(SAE_L, rel=1e-3)
    fills = _fills(res)
    assert len(fills) >= 3, res["attempts"]           # it curled to the end on at least three piles
    for f in fills:
        assert HANDBOOK[0] - 0.04 <= f <= HANDBOOK[1] + 0.03, (f, res["attempts"])
    assert HANDBOOK[0] - 0.03 <= sum(fills) / len(fills) <= HANDBOOK[1] + 0.03
    assert res["within_handbook"]


def test_the_static_heap_over_fills(cfg):
    static = copy.deepcopy(cfg)
    static["task"]["bucket_fill_factor"] = 0.0
    res = heuristic_fill(static, slopes=(15.0, 30.0), seeds=(0,))
    fills = _fills(res)
    assert fills and min(fills) > 1.0 and not res["within_handbook"], res["attempts"]
