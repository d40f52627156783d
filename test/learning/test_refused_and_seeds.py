"""Two things an evaluation must get right (a review, 2026-11-29, twelfth session):

* an episode whose told slope (the pile's plus the LiDAR's error) lies outside the range the actor was
  trained on is refused by the policy node and never armed by the supervisor: the evaluation does not run
  it with the slope observation clipped, it counts it as refused (a pile placed, nothing loaded);
* the training's episode seeds never reach the evaluation seeds (periodic 1,000,000, held-out 2,000,000,
  confirmation 3,000,000), which they did for run seeds 1-3 before training.episode_seed_offset."""
import copy
import math
from dataclasses import replace

import numpy as np
import pytest

from lhd_loading_ros.learning.evaluate import evaluate, run_policy_episode
from lhd_loading_ros.learning.train import episode_seed
from lhd_loading_ros.task.config import ConfigError, validate
from lhd_loading_ros.task.metrics import EpisodeResult, aggregate
from lhd_loading_ros.task.randomization import NOMINAL


def _result(success: bool, loaded: float, refused: bool = False) -> EpisodeResult:
    return EpisodeResult(ret=10.0 if success else -5.0, loaded=loaded, phi_final=math.radians(50 if success else 10),
                         reached_end_zone=success, failed=False, truncated=not success, steps=0 if refused else 40,
                         elapsed_s=0.0 if refused else 4.0, front_drift_pct=0.0, rear_drift_pct=0.0,
                         success_level=3 if success else 0, refused=refused)


def test_aggregate_counts_refused_attempts_as_loading_nothing_and_keeps_the_loading_figures_to_the_run_ones():
    rs = [_result(True, 30.0), _result(True, 34.0), _result(False, 12.0),
          _result(False, 0.0, refused=True), _result(True, 0.0, refused=True)]   # a refused one never succeeds
    a = aggregate(rs, 30.0)
    assert a["episodes"] == 5 and a["refused"] == 2 and a["refused_rate"] == pytest.approx(0.4)
    assert a["success_rate"] == pytest.approx(2 / 5)        # per pile placed
    assert a["success_rate_run"] == pytest.approx(2 / 3)    # per attempt run
    assert a["aml"] == pytest.approx((30 + 34 + 12) / 3)    # what the loading did: the run ones only
    assert a["elapsed_s"] == pytest.approx(4.0)
    none_run = aggregate([_result(False, 0.0, refused=True)], 30.0)
    assert none_run["success_rate"] == 0.0 and math.isnan(none_run["aml"]) and math.isnan(none_run["success_rate_run"])
    plain = [_result(True, 30.0), _result(False, 12.0)]
    assert aggregate(plain, 30.0)["success_rate"] == aggregate(plain, 30.0)["success_rate_run"] == 0.5


@pytest.fixture(scope="module")
def env():
    from lhd_sim_node.env import LhdLoadingEnv

    return LhdLoadingEnv("rld")         # the default file: piles of 15-30 deg


def test_a_told_slope_outside_the_trained_range_is_refused_as_the_policy_node_refuses_it(env):
    from lhd_loading_ros.policy.core import slope_refusal

    lo, hi = math.degrees(env.p.alpha_min), math.degrees(env.p.alpha_max)
    for pile, error, refused in ((30.0, 0.0, False), (30.0, 4.0, True), (15.0, -3.0, True), (20.0, 10.0, False)):
        _, info = env.reset(seed=7, options={"slope_deg": pile, "conditions": replace(NOMINAL, slope_error_deg=error)})
        assert info["told_slope_deg"] == pytest.approx(pile + error)
        assert bool(info["slope_refusal"]) is refused, (pile, error, info["slope_refusal"])
        # the node's own rule, on the same told slope
        assert info["slope_refusal"] == slope_refusal(math.radians(pile + error), (lo, hi))
        if refused:
            assert "outside the range the actor was trained on [15, 30]" in env.slope_refusal

    calls = []

    def policy(obs):
        calls.append(obs)
        return np.zeros(3)

    told_high = {"slope_deg": 30.0, "conditions": replace(NOMINAL, slope_error_deg=4.0)}
    r = run_policy_episode(env, policy, 7, dict(told_high), refuse=True)
    assert r.refused and not r.success and r.loaded == 0.0 and r.steps == 0 and calls == []
    r = run_policy_episode(env, policy, 7, dict(told_high), refuse=False)      # the training's way: clipped, run
    assert not r.refused and r.steps > 0 and len(calls) == r.steps
    assert all(o[11] == pytest.approx(1.0) for o in calls)      # the slope observation clipped to the range's top
    with pytest.raises(RuntimeError, match="inside the trained range"):
        env.reset(seed=7, options={"slope_deg": 20.0})
        env.refused_result()


def test_evaluate_counts_the_refused_and_the_rest_as_before(env):
    """The same 8 stratified episodes under the `sensors` stress case: no told slope leaves the range,
    so refuse changes nothing; a stress that pushes some out (a 12 deg LiDAR bias, by hand) refuses
    exactly the episodes whose told slope is outside 15-30 deg."""
    from lhd_loading_ros.learning import evaluate as ev_mod

    act = lambda o: np.array([1.0, 0.0, 0.0])    # noqa: E731 - full wheels, the arm still
    a = evaluate(env, act, 8, 2_000_000, 30.0, breakdown=False, refuse=True)
    b = evaluate(env, act, 8, 2_000_000, 30.0, breakdown=False, refuse=False)
    assert a["refused"] == 0 and {k: a[k] for k in ("success_rate", "aml", "ar")} == {k: b[k] for k in
                                                                                     ("success_rate", "aml", "ar")}
    biased = []
    orig = ev_mod.episode_conditions

    def with_bias(i, seed):
        s, opts = orig(i, seed)
        opts["conditions"] = replace(NOMINAL, slope_error_deg=12.0)
        biased.append(opts["slope_deg"] + 12.0)
        return s, opts

    ev_mod.episode_conditions = with_bias
    try:
        c = evaluate(env, act, 8, 2_000_000, 30.0, breakdown=False, refuse=True)
    finally:
        ev_mod.episode_conditions = orig
    want = sum(1 for t in biased if not 15.0 <= t <= 30.0)      # piles 15/20/25/30 told 27/32/37/42
    assert want == 6 and c["refused"] == want and c["failures"]["refused"] == want
    assert sum(c["zones_from"].values()) == 8 - want            # a refused episode is judged by no zones


def test_training_episode_seeds_stay_clear_of_every_evaluation_seed(cfg):
    """Computed here, not from the code's own bound: the default file's offset puts the seeds of run seeds
    0-99 (their first 20,000 episodes, more than a 300,000-step run has) above every evaluation set; without
    the offset (the parameter files of every run before it) run seed 2 drew the held-out piles."""
    off = cfg["training"]["episode_seed_offset"]
    assert off == 1_000_000_000
    eval_sets = [set(range(base, base + 1000)) for base in (1_000_000, 2_000_000, 3_000_000, 4_000_000)]
    for run in range(100):
        seeds = {episode_seed(run, k, off) for k in range(20_000)}
        assert min(seeds) >= off and all(not (seeds & e) for e in eval_sets), run
    old = {episode_seed(2, k) for k in range(200)}
    assert len(old & set(range(2_000_000, 2_000_120))) == 114           # 2,000,006 .. 2,000,119
    assert episode_seed(2, 0) == 2 * 1_000_003 and episode_seed(2, 0, off) == off + 2 * 1_000_003


def test_a_periodic_evaluation_inside_the_training_seeds_is_refused(cfg):
    c = copy.deepcopy(cfg)
    c["training"]["eval_seed"] = c["training"]["episode_seed_offset"] - 10
    with pytest.raises(ConfigError, match="episode_seed_offset"):
        validate(c)
    c["training"]["episode_seed_offset"] = 0       # the old stream: no such promise, no check
    validate(c)
