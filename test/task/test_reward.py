"""Each of the ten reward terms against hand computation from the paper's equations."""
import math
from collections import deque

import pytest

from lhd_loading_ros.task import reward as R
from lhd_loading_ros.task.metrics import EpisodeResult, aggregate, success_level
from lhd_loading_ros.task.state import LhdState
from lhd_loading_ros.task.zones import Zones

Z = Zones(x_min=0.7, x_max=1.1, z_min=0.35, x_cutoff=1.6, x_obs_start=-0.1, x_obs_end=1.0, y_half=0.2, z_top=0.4)
r = math.radians


def test_traj_inside_bounds_is_free(params):
    a = R.traj_angles(0.3, 0.05, 0.27, 0.05, Z, 0.68, params)
    # upper: atan2(0.34-0.05, 0.7-0.3) = 35.94 deg; lower: rail ~ 0.3^17 ~ 0 -> atan2(-0.05, 0.1) = -26.57 deg
    assert math.degrees(a[0]) == pytest.approx(0.0)
    assert math.degrees(a[1]) == pytest.approx(-26.565, abs=1e-3)
    assert math.degrees(a[2]) == pytest.approx(35.942, abs=1e-3)
    assert R.r_traj(*a, True, params) == 0.0


def test_traj_too_steep_before_x_min(params):
    a = R.traj_angles(0.3, 0.05, 0.29, 0.0, Z, 0.68, params)  # atan2(0.05, 0.01) = 78.7 deg > 35.9
    assert R.r_traj(*a, True, params) == -60.0
    assert R.r_traj(*a, False, params) == 0.0  # only inside the pile


def test_traj_rail_forces_lifting_near_x_max(params):
    # rail at x = 0.95: (0.95 + 0.1 + 1.0 - 1.1)^17 = 0.95^17 = 0.41812
    assert R.z_rail(0.95, 1.1, params) == pytest.approx(0.95 ** 17)
    a = R.traj_angles(0.95, 0.2, 0.93, 0.2, Z, 0.68, params)
    assert math.degrees(a[1]) == pytest.approx(math.degrees(math.atan2(0.95 ** 17 - 0.2, 0.1)))
    assert R.r_traj(*a, True, params) == -60.0  # moving flat while the rail rises ahead


def test_midgoal(params):
    # -25 * |0.32 - 0.54| / 0.44 = -12.5
    assert R.r_midgoal(0.32, params) == pytest.approx(-12.5)
    assert R.r_midgoal(0.54, params) == 0.0


def test_inact(params):
    assert R.r_inact(-0.05, 0.2, 0.6, params) == -50.0     # |-0.05/-0.191| = 0.26 < 0.5
    assert R.r_inact(-0.191, 0.05, 0.6, params) == -50.0   # |0.05/0.2| = 0.25 < 0.5
    assert R.r_inact(-0.1, 0.11, 0.6, params) == 0.0       # 0.52 and 0.55
    assert R.r_inact(0.0, 0.0, 0.5, params) == 0.0         # before x_midgoal


def test_drift(params):
    assert R.r_drift(True, 0.0, 0.0, params) == -5.0
    assert R.r_drift(True, -0.191, 0.0, params) == 0.0
    assert R.r_drift(False, 0.0, 0.0, params) == 0.0


def test_stuck(params):
    assert R.r_stuck(deque([0.001] * 9), params) == -5.0    # T_stuck + 1 = 9 steps below 0.005 m
    assert R.r_stuck(deque([0.001] * 8), params) == 0.0
    assert R.r_stuck(deque([0.001] * 8 + [0.01]), params) == 0.0


def test_dump_forward_tilt_reading(params):
    """Default (r_dump_sign = -1, the paper's prose): tilted forward by 40 deg or more."""
    assert params.r_dump_sign == -1
    assert R.r_dump(r(-40), params) == -20.0
    assert R.r_dump(r(-39.9), params) == 0.0
    assert R.r_dump(r(45), params) == 0.0      # curled back past 40 deg: what the success test asks for


def test_dump_literal_inequality(params):
    import dataclasses
    lit = dataclasses.replace(params, r_dump_sign=1)
    assert R.r_dump(r(40), lit) == -20.0
    assert R.r_dump(r(39.9), lit) == 0.0


def test_bottom(params):
    assert R.r_bottom(0.05, 0.10, params) == -5.0
    assert R.r_bottom(0.095, 0.10, params) == 0.0  # within the 1 cm tolerance
    assert R.r_bottom(0.2, 0.10, params) == 0.0


def test_weight(params):
    """Default: increments (R_weight per kg entering the bucket); the paper's form pays W^t."""
    import dataclasses
    assert params.r_weight_increments == 1
    assert R.r_weight(12.5, params, 10.0) == 2.5
    assert R.r_weight(30.0, params, 30.0) == 0.0          # holding a full bucket earns nothing
    paper = dataclasses.replace(params, r_weight_increments=0)
    assert R.r_weight(12.5, paper, 10.0) == 12.5


def test_weight_increments_sum_to_the_final_load(params):
    tr = R.RewardTracker(params, Z, 0.68)
    s = LhdState(0.30, 0.0, 0.02, 0.0, 0.3, False, 0.0, 0.0, 0.0, 0.0)
    tr.reset(s, W0=1.5)
    loads = [3.0, 7.5, 7.5, 20.0, 31.0, 31.0]
    total = sum(tr.step(s, 0.0, 0.0, W, True, 0.0, "running")["weight"] for W in loads)
    assert total == pytest.approx(31.0 - 1.5)


def test_success_pitch_target_lies_above_the_success_test(params):
    """Default: target 40 + 7.5 deg, so Delta_pitch is maximal on [42.5, 52.5] deg (all SL-valid)
    and smaller at 36 deg, where the paper's target would pay in full with SL = 0."""
    assert math.degrees(params.phi_target) == pytest.approx(47.5)
    assert R.success_deltas(30.0, r(43), params)[1] == 1.0
    assert R.success_deltas(30.0, r(52), params)[1] == 1.0
    assert R.success_deltas(30.0, r(36), params)[1] < 0.95
    assert R.r_success(30.0, r(44), params) > R.r_success(30.0, r(37), params)


def test_success_reward_requires_the_success_test(params):
    """Default: nothing for reaching the end zone below 20 kg or at phi^T <= 40 deg."""
    assert params.r_success_requires_sl == 1
    assert R.r_success(19.9, r(45), params) == 0.0
    assert R.r_success(30.0, r(40), params) == 0.0
    assert R.r_success(30.0, r(44), params) == pytest.approx(40 * 30)


def test_training_pitch_margin_raises_only_r_success_s_pitch_test(params):
    """r_success_pitch_margin (training): nothing paid at 41 and 42.9 deg with a 3 deg margin, in
    full above 43 deg; the paper's success level of the same attempt is unchanged (SL 5 at 41 deg)."""
    import dataclasses
    from lhd_loading_ros.task.metrics import success_level
    m3 = dataclasses.replace(params, r_success_pitch_margin=r(3.0))
    m0 = dataclasses.replace(params, r_success_pitch_margin=0.0)
    assert R.r_success(30.0, r(41), m0) > 0.0
    assert R.r_success(30.0, r(41), m3) == 0.0
    assert R.r_success(30.0, r(42.9), m3) == 0.0
    assert R.r_success(30.0, r(44), m3) == pytest.approx(R.r_success(30.0, r(44), m0)) == pytest.approx(40 * 30)
    assert success_level(30.0, r(41), m3.phi_thresh_pitch) == 5
    # off when r_success does not require the success test (the paper's printed term)
    paper = dataclasses.replace(m3, r_success_requires_sl=0)
    assert R.r_success(30.0, r(41), paper) > 0.0


def test_training_mass_margin_raises_only_r_success_s_mass_test(params):
    """r_success_mass_margin (training, kg): with 4 kg nothing is paid at 20 or 23.9 kg, and from 24 kg
    exactly what the paper's test pays: R_success (Delta_W + Delta_pitch) / 2 max(W, W_target), by hand
    Delta_W(24) = 1 - ((6 + ln 6) - (1 + ln 1)) / ((30 + ln 30) - (1 + ln 1)) = 0.790383, Delta_pitch 1 at
    44 deg (inside the 42.5-52.5 deg band), so 40 x 1.790383 / 2 x 30 = 1074.23. The paper's success
    level of the same attempts is unchanged (SL 1 at 20 kg)."""
    import dataclasses
    m4 = dataclasses.replace(params, r_success_mass_margin=4.0)
    m0 = dataclasses.replace(params, r_success_mass_margin=0.0)
    assert R.r_success(20.0, r(44), m0) > 0.0
    assert R.r_success(20.0, r(44), m4) == 0.0
    assert R.r_success(23.9, r(44), m4) == 0.0
    d_w = 1 - ((6 + math.log(6)) - 1) / ((30 + math.log(30)) - 1)
    assert R.r_success(24.0, r(44), m4) == pytest.approx(40 * (d_w + 1) / 2 * 30) == pytest.approx(1074.2313, abs=1e-3)
    assert R.r_success(24.0, r(44), m4) == R.r_success(24.0, r(44), m0)
    assert R.r_success(30.0, r(44), m4) == pytest.approx(40 * 30)
    assert success_level(20.0, r(44), m4.phi_thresh_pitch) == 1
    # the two margins together: both tests must pass
    both = dataclasses.replace(m4, r_success_pitch_margin=r(3.0))
    assert R.r_success(30.0, r(42.9), both) == 0.0 and R.r_success(23.0, r(44), both) == 0.0
    assert R.r_success(24.0, r(44), both) == pytest.approx(1074.2313, abs=1e-3)
    # off when r_success does not require the success test (the paper's printed term)
    assert R.r_success(21.0, r(44), dataclasses.replace(m4, r_success_requires_sl=0)) > 0.0


def test_the_mass_margin_is_never_in_the_config_hash(cfg):
    """task.r_success_mass_margin_kg is reward shaping, not what the actor sees: a parameter file
    without the key reads as 0, and 0, 4 kg and an absent key give one hash, so an actor trained with
    the margin runs on the project's file (and on the one shipped beside an actor trained without)."""
    import copy
    from lhd_loading_ros.task.config import config_hash, hash_matches, validate
    assert cfg["task"]["r_success_mass_margin_kg"] == 0.0
    stripped = copy.deepcopy(cfg)
    del stripped["task"]["r_success_mass_margin_kg"]
    assert validate(copy.deepcopy(stripped))["task"]["r_success_mass_margin_kg"] == 0.0
    m4 = copy.deepcopy(cfg)
    m4["task"]["r_success_mass_margin_kg"] = 4.0
    assert config_hash(cfg) == config_hash(stripped) == config_hash(m4)
    assert hash_matches(config_hash(m4), cfg)
    bad = copy.deepcopy(cfg)
    bad["task"]["r_success_mass_margin_kg"] = -1.0
    with pytest.raises(Exception, match="r_success_mass_margin_kg"):
        validate(bad)


def test_success(params):
    import dataclasses
    params = dataclasses.replace(params, phi_target=r(40), r_success_requires_sl=0)   # the paper's printed term
    assert R.r_success(30.0, r(40), params) == pytest.approx(40 * 1.0 * 30)
    # Delta_W(15): delta = (15 + ln 15) - (1 + ln 1) = 16.70805; max at W = 0: 30 + ln 30 - 1 = 32.40120
    d_w = 1 - 16.708050201 / 32.401197273
    assert R.success_deltas(15.0, r(40), params)[0] == pytest.approx(d_w)
    assert R.r_success(15.0, r(40), params) == pytest.approx(40 * (d_w + 1) / 2 * 30)
    # Delta_pitch(20 deg): (20 + ln 20) - (5 + ln 5) = 16.386294; max distance 100 deg: 97.995732
    assert R.success_deltas(30.0, r(20), params)[1] == pytest.approx(1 - 16.386294361 / 97.995732274)
    assert R.r_success(36.0, r(42), params) == pytest.approx(40 * (R.success_deltas(36.0, r(42), params)[0] + 1) / 2 * 36)
    assert R.delta_big(0.0, 30.0, 1.0, 30.0) == 0.0 and R.delta_big(29.5, 30.0, 1.0, 30.0) == 1.0


def test_zone(params):
    assert R.r_zone(True, params) == -2000.0 and R.r_zone(False, params) == 0.0


def test_tracker_sums_the_ten_terms(params):
    tr = R.RewardTracker(params, Z, 0.68)
    s0 = LhdState(0.30, 0.0, 0.02, 0.0, 0.3, False, 0.0, 0.0, 0.0, 0.0, x_bottom=0.0, z_bottom=0.0)
    tr.reset(s0)
    s1 = LhdState(0.32, 0.0, 0.02, 0.0, 0.3, True, 0.0, 0.0, 0.0, 0.0, x_bottom=0.02, z_bottom=0.0)
    terms = tr.step(s1, 0.0, 0.0, 10.0, True, 0.0, "running")
    assert set(terms) == set(R.TERMS)
    assert terms["midgoal"] == pytest.approx(-12.5) and terms["drift"] == -5.0 and terms["weight"] == 10.0
    assert terms["success"] == 0.0 and terms["zone"] == 0.0
    terms = tr.step(s1, 0.0, 0.0, 10.0, True, 0.0, "failure")
    assert terms["zone"] == -2000.0


def test_success_level_bands_and_aggregate():
    th = r(40)
    assert [success_level(w, r(41), th) for w in (28, 27.9, 26, 24, 22, 20, 19.9)] == [5, 4, 4, 3, 2, 1, 0]
    assert success_level(30, r(40), th) == 0  # phi^T must exceed the threshold
    e = dict(phi_final=r(41), failed=False, truncated=False, steps=40, elapsed_s=4.0, front_drift_pct=10.0,
             rear_drift_pct=20.0)
    res = [EpisodeResult(ret=100.0, loaded=30.0, reached_end_zone=True, success_level=5, **e),
           EpisodeResult(ret=-100.0, loaded=15.0, reached_end_zone=True, success_level=0, **e)]
    agg = aggregate(res, 30.0)
    assert agg["ar"] == 0.0 and agg["aml"] == 22.5 and agg["aff"] == 0.75 and agg["asl"] == 2.5
    assert agg["success_rate"] == 0.5 and agg["end_zone_rate"] == 1.0 and agg["episodes"] == 2
    with pytest.raises(ValueError):
        aggregate([], 30.0)


def test_success_is_the_papers_definition():
    """SL >= 1 at the end counts, a timeout included (paper, experimental settings); the
    restricted zone never does."""
    e = dict(ret=0.0, loaded=30.0, phi_final=r(45), steps=200, elapsed_s=20.0, front_drift_pct=0.0,
             rear_drift_pct=0.0, success_level=5)
    assert EpisodeResult(reached_end_zone=False, failed=False, truncated=True, **e).success
    assert EpisodeResult(reached_end_zone=True, failed=False, truncated=False, **e).success
    assert not EpisodeResult(reached_end_zone=False, failed=True, truncated=False, **e).success
    assert not EpisodeResult(reached_end_zone=True, failed=False, truncated=False,
                             **{**e, "success_level": 0}).success
