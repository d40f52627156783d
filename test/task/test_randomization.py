"""Domain randomisation, the pure part (task/randomization.py): ranges from the config, the
episode draw, the per-step sensor errors. Expectations are computed here from the definitions
(uniform ranges, Gaussian spread, hold and delay), not read back from the module."""
import copy
import re
import math

import numpy as np
import pytest

from lhd_loading_ros.task.config import ConfigError, config_hash, load_config, validate
from lhd_loading_ros.task.randomization import (NOMINAL, Conditions, ObservationCorruptor, RandomizationRanges,
                                                delay_chunks, draw)


# how the learner learned (clipped double Q, the slope curriculum): never in the hash
NEVER_HASHED = ("twin_critics", "slope_curriculum", "slope_curriculum_bins", "slope_curriculum_window",
                "slope_curriculum_uniform", "slope_curriculum_reward_test", "lr_final_scale", "lr_decay_from",
                "demo_share", "demo_crowd_min", "demo_crowd_max", "demo_pre_curl", "demo_bc", "demo_until_step", "critic_huber", "actor_preact_l2", "demo_q_lower_bound", "noise_after_decay",
                "demo_bc_return_filter", "demo_told_zones", "demo_end_zone_stop", "demo_push_curl", "demo_late_lift", "demo_told_high", "demo_failing_share",
                "demo_drift_confirm", "demo_where_teacher_wins",
                "episode_seed_offset")


GAIN_KEYS = ("drive_gain_min", "drive_gain_max", "hydraulic_gain_min", "hydraulic_gain_max")


def without_unit_gains(c):
    """The actuator gains (2026-11-28) at 1, their default, are left out of the hash; so is the share of
    starts from rest, the surface relief, the end-zone node's zones and the arm's angle-sensor offsets (2026-11-29)
    at 0."""
    r = c.get("randomization")
    if r is not None and all(r.get(k, 1.0) == 1.0 for k in GAIN_KEYS):
        c = {**c, "randomization": {k: v for k, v in r.items() if k not in GAIN_KEYS}}
    for key in ("rest_start_share", "surface_sd_max", "zones_at_nominal_density", "arm_offset_max_deg",
                "slope_error_high_share", "drift_flag_lag_max_s", "slope_error_small_share", "slope_error_small_max_deg"):
        r = c.get("randomization")
        if r is not None and r.get(key, 0.0) == 0.0:
            c = {**c, "randomization": {k: v for k, v in r.items() if k != key}}
    return without_stall_start(c)


def without_stall_start(c):
    """sim.attack_min_depth (2026-11-29, fifteenth session) at 0, its default, is left out of the hash."""
    if "sim" in c and c["sim"].get("attack_min_depth", 0.0) == 0.0:
        c = {**c, "sim": {k: v for k, v in c["sim"].items() if k != "attack_min_depth"}}
    return c


@pytest.fixture(scope="module")
def cfg():
    return load_config()


def test_the_shipped_section_is_off_and_a_disabled_section_leaves_the_hash_alone(cfg):
    assert cfg["randomization"]["enabled"] == 0
    without = without_stall_start({k: v for k, v in cfg.items() if k != "randomization"})
    # the tilt penalty is off too: its keys stay out (test_tilt_reward.py)
    without["task"] = {k: v for k, v in cfg["task"].items() if k not in ("r_tilt_per_deg", "r_tilt_free_deg", "r_tilt_ramp_after_success", "r_tilt_ramp_steps", "r_tilt_ramp_pitch_margin", "midgoal_from_pile", "reward_zones_from_pile", "r_success_mass_margin_kg")}
    without["training"] = {k: v for k, v in cfg["training"].items() if k not in NEVER_HASHED}
    import hashlib
    import json
    assert config_hash(cfg) == hashlib.sha256(json.dumps(without, sort_keys=True).encode()).hexdigest()[:16]
    on = copy.deepcopy(cfg)
    on["randomization"]["enabled"] = 1
    assert config_hash(on) != config_hash(cfg)
    # an actor trained with this section switched on may run on this config (same observation and filters)
    from lhd_loading_ros.task.config import hash_matches
    assert hash_matches(config_hash(on), cfg) and hash_matches(config_hash(cfg), cfg)
    assert not hash_matches("0123456789abcdef", cfg) and not hash_matches(None, cfg)
    other = copy.deepcopy(cfg)
    other["paper"]["reward"]["R_zone"] = 1000.0
    assert not hash_matches(config_hash(other), cfg)
    on2 = copy.deepcopy(on)
    on2["randomization"]["vx_noise"] = 0.05                    # a randomised run's ranges are part of its identity
    assert config_hash(on2) != config_hash(on)
    # the actuator gains (2026-11-28) at 1, their default: the hash randomised actors had before the keys
    # existed (computed here without them); set, part of the identity
    keys = ("drive_gain_min", "drive_gain_max", "hydraulic_gain_min", "hydraulic_gain_max")
    before = copy.deepcopy(on)
    # likewise the share of starts from rest, the surface relief, the end-zone node's zones and the arm's
    # angle-sensor offsets (2026-11-29) at 0
    before["randomization"] = {k: v for k, v in on["randomization"].items()
                               if k not in keys + ("rest_start_share", "surface_sd_max", "zones_at_nominal_density",
                                                   "arm_offset_max_deg", "slope_error_high_share",
                                                   "drift_flag_lag_max_s", "slope_error_small_share",
                                                   "slope_error_small_max_deg")}
    assert all(on["randomization"][k] == 1.0 for k in keys) and on["randomization"]["rest_start_share"] == 0.0
    assert on["randomization"]["surface_sd_max"] == 0.0 and on["randomization"]["zones_at_nominal_density"] == 0
    assert on["randomization"]["arm_offset_max_deg"] == 0.0
    assert config_hash(on) == hashlib.sha256(json.dumps(
        {**{k: v for k, v in without_stall_start(before).items() if k not in ("training",)},
         "task": without["task"], "training": without["training"]}, sort_keys=True).encode()).hexdigest()[:16]
    gains = copy.deepcopy(on)
    gains["randomization"].update(drive_gain_min=0.8, hydraulic_gain_min=0.75)
    assert config_hash(gains) != config_hash(on) and hash_matches(config_hash(gains), gains)
    arm = copy.deepcopy(on)
    arm["randomization"]["arm_offset_max_deg"] = 2.5          # set: part of a randomised actor's identity
    assert config_hash(arm) != config_hash(on)
    # an actor trained without the offsets runs on a file that has them (a training-only range), as with the
    # other keys; one trained with them runs on its own file, or on it with the section off (lhd ship's)
    assert hash_matches(config_hash(on), arm) and hash_matches(config_hash(arm), arm)
    assert hash_matches(config_hash(arm), {**arm, "randomization": {**arm["randomization"], "enabled": 0}})


@pytest.mark.parametrize("key,value,needle", [
    ("vx_noise", -0.1, "randomization.vx_noise"),
    ("vx_dropout_probability", 1.5, "randomization.vx_dropout_probability"),
    ("density_min", 2500.0, "randomization.density_min <= randomization.density_max"),
    ("tyre_friction_max", 0.5, "randomization.tyre_friction_min <= randomization.tyre_friction_max"),
    ("d_attack_max", 0.05, "paper.episode.d_attack_min <= randomization.d_attack_max"),
    ("enabled", 2, "randomization.enabled"),
    ("drive_gain_min", 1.2, "randomization.drive_gain_min <= randomization.drive_gain_max"),
    ("hydraulic_gain_max", 0.0, "randomization.hydraulic_gain_max"),
])
def test_bad_values_are_refused_naming_the_key(cfg, key, value, needle):
    bad = copy.deepcopy(cfg)
    bad["randomization"][key] = value
    with pytest.raises(ConfigError, match=needle.replace(".", r"\.")):
        validate(bad)


def test_draws_cover_the_ranges_and_only_them(cfg):
    rr = RandomizationRanges.from_config(cfg)
    r = cfg["randomization"]
    rng = np.random.default_rng(0)
    cs = [draw(rng, rr) for _ in range(2000)]
    chunk = cfg["sim"]["timestep"] * cfg["sim"]["fee_every"]          # 0.02 s
    for name, lo, hi in (("slope_error_deg", -r["slope_error_max_deg"], r["slope_error_max_deg"]),
                         ("heading_deg", -r["heading_max_deg"], r["heading_max_deg"]),
                         ("lateral_offset", -r["lateral_offset_max"], r["lateral_offset_max"]),
                         ("tyre_friction", r["tyre_friction_min"], r["tyre_friction_max"]),
                         ("d_attack", cfg["paper"]["episode"]["d_attack_min"], r["d_attack_max"]),
                         ("attack_speed_fraction", r["attack_speed_min_fraction"], 1.0)):
        v = np.array([getattr(c, name) for c in cs])
        assert v.min() >= lo and v.max() <= hi, name
        # uniform: 2000 draws come within 1 % of the width of both ends, the mean near the middle
        assert v.min() < lo + 0.01 * (hi - lo) and v.max() > hi - 0.01 * (hi - lo), name
        assert abs(v.mean() - 0.5 * (lo + hi)) < 0.03 * (hi - lo), name
    # delays: every multiple of 20 ms from 0 to 100 ms, each about 1/6 of the draws
    for name in ("drive_delay_s", "hydraulic_delay_s"):
        k = np.array([round(getattr(c, name) / chunk) for c in cs])
        assert np.allclose([getattr(c, name) for c in cs], k * chunk)
        counts = np.bincount(k, minlength=6)
        assert len(counts) == 6 and all(abs(n / 2000 - 1 / 6) < 0.03 for n in counts)
    assert {c.vx_delay_steps for c in cs} == set(range(r["vx_delay_steps_max"] + 1))
    # the soil ranges: the section's, wider than the paper's gravel
    s = cs[0].soil
    assert s.density == (r["density_min"], r["density_max"])
    assert s.phi == pytest.approx((math.radians(r["phi_min_deg"]), math.radians(r["phi_max_deg"])))
    assert s.rocks[1] == r["rocks_max"] and s.cohesion[1] == r["cohesion_max"]
    assert s.density[0] < cfg["pile"]["density_min"] and s.density[1] > cfg["pile"]["density_max"]


def test_a_share_told_too_steep_leaves_the_other_draws_alone(cfg):
    """randomization.slope_error_high_share (2026-11-30): that share of the episodes is told the slope
    U(max / 2, max) too steep, the rest U(-max, max); at 0 every draw is the one before the key (the same
    generator stream, so earlier randomised evaluations replay); set, it is part of a randomised actor's
    identity, and an actor trained without it runs on a file that has it."""
    from lhd_loading_ros.task.config import hash_matches
    on = copy.deepcopy(cfg)
    on["randomization"]["enabled"] = 1
    e = on["randomization"]["slope_error_max_deg"]
    assert on["randomization"]["slope_error_high_share"] == 0.0
    high = copy.deepcopy(on)
    high["randomization"]["slope_error_high_share"] = 0.4
    rng1 = np.random.default_rng(5)
    rr = RandomizationRanges.from_config(high)
    cs = [draw(rng1, rr) for _ in range(4000)]
    err = np.array([c.slope_error_deg for c in cs])
    assert err.min() >= -e and err.max() <= e
    # by hand: P(err >= e/2) = 0.4 + 0.6 x 1/4 = 0.55; P(err < 0) = 0.6 x 1/2 = 0.30
    assert np.mean(err >= 0.5 * e) == pytest.approx(0.55, abs=0.03)
    assert np.mean(err < 0.0) == pytest.approx(0.30, abs=0.03)
    # the other ranges drawn as before: the share's draws come after every other one
    g_high, g_off = np.random.default_rng(9), np.random.default_rng(9)
    one, ref = draw(g_high, rr), draw(g_off, RandomizationRanges.from_config(on))
    assert (one.heading_deg, one.d_attack, one.tyre_friction) == (ref.heading_deg, ref.d_attack, ref.tyre_friction)
    # at 0 it draws nothing (so a stream of episodes is the one before the key): the ranges of this file draw
    # only uniforms and integers, and a generator that refuses random() is never asked for one
    class NoRandom:
        def __init__(self, g):
            self.g, self.calls = g, []

        def uniform(self, *a):
            self.calls.append("uniform")
            return self.g.uniform(*a)

        def integers(self, *a):
            self.calls.append("integers")
            return self.g.integers(*a)

        def random(self):
            raise AssertionError("random() drawn with slope_error_high_share 0")

    assert on["randomization"]["rest_start_share"] == 0.0
    g = NoRandom(np.random.default_rng(3))
    draw(g, RandomizationRanges.from_config(on))
    # by hand, what one episode drew before the key: slope error, tyre friction, start distance, attack speed,
    # heading and lateral offset (uniforms); v_x delay and the two actuator delays (integers)
    assert sorted(g.calls) == ["integers"] * 3 + ["uniform"] * 6
    with pytest.raises(AssertionError, match="random"):
        draw(NoRandom(np.random.default_rng(3)), rr)
    assert config_hash(high) != config_hash(on)
    assert hash_matches(config_hash(on), high) and hash_matches(config_hash(high), high)
    # its evaluation file (the section off, the share kept) takes it; a file without the share does not
    assert hash_matches(config_hash(high), {**high, "randomization": {**high["randomization"], "enabled": 0}})
    assert not hash_matches(config_hash(high), {**on, "randomization": {**on["randomization"], "enabled": 0}})
    with pytest.raises(ConfigError, match="randomization.slope_error_high_share"):
        bad = copy.deepcopy(high)
        bad["randomization"]["slope_error_high_share"] = 1.5
        validate(bad)


def test_a_share_told_right_as_the_lidar_gives_it(cfg):
    """randomization.slope_error_small_share / slope_error_small_max_deg (2026-12-02): that share of the episodes
    draws the error U(-small, small), the LiDAR right; the others the whole range's. Counted by hand, with the
    told-too-steep share under it: at 0 nothing is drawn for it (the stream is the one before the keys)."""
    from lhd_loading_ros.task.config import hash_matches
    on = copy.deepcopy(cfg)
    on["randomization"]["enabled"] = 1
    e = on["randomization"]["slope_error_max_deg"]
    assert (on["randomization"]["slope_error_small_share"], on["randomization"]["slope_error_small_max_deg"]) == (0.0, 0.0)
    small = copy.deepcopy(on)
    small["randomization"].update(slope_error_small_share=0.5, slope_error_small_max_deg=1.0)
    rr = RandomizationRanges.from_config(validate(copy.deepcopy(small)))
    err = np.array([draw(np.random.default_rng(k), rr).slope_error_deg for k in range(4000)])
    # by hand: P(|err| <= 1) = 0.5 + 0.5 x (2 / 2e); P(err >= e/2) = 0.5 x 1/4
    assert np.mean(np.abs(err) <= 1.0) == pytest.approx(0.5 + 0.5 * 2.0 / (2.0 * e), abs=0.03)
    assert np.mean(err >= 0.5 * e) == pytest.approx(0.125, abs=0.02)
    assert err.min() >= -e and err.max() <= e
    # with the told-too-steep share 0.4 as well: told too steep by e/2 or more in (1 - 0.5) x (0.4 + 0.6 / 4)
    both = copy.deepcopy(small)
    both["randomization"]["slope_error_high_share"] = 0.4
    rb = RandomizationRanges.from_config(validate(copy.deepcopy(both)))
    eb = np.array([draw(np.random.default_rng(k), rb).slope_error_deg for k in range(4000)])
    assert np.mean(eb >= 0.5 * e) == pytest.approx(0.5 * 0.55, abs=0.03)
    # every other draw as without it (drawn after them); at 0 the draws are exactly the earlier ones
    one, ref = draw(np.random.default_rng(9), rr), draw(np.random.default_rng(9), RandomizationRanges.from_config(on))
    assert (one.heading_deg, one.d_attack, one.tyre_friction) == (ref.heading_deg, ref.d_attack, ref.tyre_friction)
    assert [draw(np.random.default_rng(k), RandomizationRanges.from_config(on)).slope_error_deg for k in range(50)] == \
        [float(np.random.default_rng(k).uniform(-e, e)) for k in range(50)]
    # part of the identity; the evaluation file without the keys refuses such an actor
    assert config_hash(small) != config_hash(on)
    assert hash_matches(config_hash(on), small) and hash_matches(config_hash(small), small)
    assert not hash_matches(config_hash(small), on)
    for bad_share, bad_max, what in ((0.5, 0.0, "> 0 where"), (0.5, e + 1.0, "<= randomization.slope_error_max_deg"),
                                     (1.5, 1.0, "slope_error_small_share")):
        bad = copy.deepcopy(on)
        bad["randomization"].update(slope_error_small_share=bad_share, slope_error_small_max_deg=bad_max)
        with pytest.raises(ConfigError, match=re.escape(what)):
            validate(bad)


def test_delay_chunks_refuses_what_the_simulator_cannot_do():
    assert delay_chunks(0.0, 0.02, 5) == 0 and delay_chunks(0.06, 0.02, 5) == 3 and delay_chunks(0.1, 0.02, 5) == 5
    for bad in (0.03, 0.12, -0.02):
        with pytest.raises(ValueError, match="multiple of the 0.02 s chunk"):
            delay_chunks(bad, 0.02, 5)


def test_nominal_sensors_pass_through_and_draw_nothing():
    rng = np.random.default_rng(3)
    before = rng.bit_generator.state
    s = ObservationCorruptor(NOMINAL, rng)
    for k in range(50):
        assert s.observe(0.01 * k, 0.3) == (0.01 * k, 0.3)
    assert rng.bit_generator.state == before


def test_speed_noise_spread_delay_and_slope_error():
    rng = np.random.default_rng(1)
    c = Conditions(vx_noise=0.025, vx_delay_steps=1, slope_error_deg=-7.0, slope_noise_deg=0.5)
    s = ObservationCorruptor(c, rng)
    true_v = np.sin(np.arange(8000) * 0.05) * 0.3
    out = np.array([s.observe(v, math.radians(20.0)) for v in true_v])
    err = out[1:, 0] - true_v[:-1]                       # one step late, then noisy
    assert abs(err.mean()) < 0.002 and err.std() == pytest.approx(0.025, rel=0.05)
    a = np.degrees(out[:, 1])
    assert a.mean() == pytest.approx(13.0, abs=0.03) and a.std() == pytest.approx(0.5, rel=0.05)
    s0 = ObservationCorruptor(Conditions(vx_delay_steps=2), np.random.default_rng(0))
    seen = [s0.observe(v, 0.0)[0] for v in (1.0, 2.0, 3.0, 4.0)]
    assert seen == [1.0, 1.0, 1.0, 2.0]                  # the oldest kept sample until the delay line is full


def test_dropouts_hold_the_last_value_for_bounded_runs():
    p, m = 0.3, 3
    s = ObservationCorruptor(Conditions(vx_dropout_probability=p, vx_dropout_max_steps=m), np.random.default_rng(2))
    vals = np.arange(1, 20001, dtype=float)              # every true value distinct: a repeat is a hold
    out = np.array([s.observe(v, 0.0)[0] for v in vals])
    held = out[1:] == out[:-1]
    runs, n = [], 0
    for h in held:
        if h:
            n += 1
        elif n:
            runs.append(n)
            n = 0
    assert max(runs) == m
    # hold probability: a step holds with p unless m holds just happened. Stationary share of held steps for a
    # run-length cap m: sum_{k=1..m} p^k / sum_{k=0..m} p^k (a Markov chain on the run length, solved by hand)
    share = sum(p ** k for k in range(1, m + 1)) / sum(p ** k for k in range(0, m + 1))
    assert held.mean() == pytest.approx(share, abs=0.01)
    # a held value is always a value actually seen before (never invented)
    assert set(out) <= set(vals)


def test_the_training_pitch_margin_is_a_training_only_setting(cfg):
    """task.r_success_pitch_margin_deg changes the reward, not what the actor sees: an actor trained
    before the key existed (key absent from its hash), with this config's margin, with another margin
    named on its card, or with randomisation too, runs on this config; another change does not."""
    import hashlib
    import json
    from lhd_loading_ros.task.config import hash_matches

    def raw(c):       # the hash by its definition, written out here (the tilt penalty off: its keys out)
        c = {k: v for k, v in c.items() if k != "randomization" or c["randomization"]["enabled"]}
        c = without_unit_gains(c)
        c["task"] = {k: v for k, v in c["task"].items() if k not in ("r_tilt_per_deg", "r_tilt_free_deg", "r_tilt_ramp_after_success", "r_tilt_ramp_steps", "r_tilt_ramp_pitch_margin", "midgoal_from_pile", "reward_zones_from_pile", "r_success_mass_margin_kg")}
        c["training"] = {k: v for k, v in c["training"].items() if k not in NEVER_HASHED}
        return hashlib.sha256(json.dumps(c, sort_keys=True).encode()).hexdigest()[:16]
    old = copy.deepcopy(cfg)
    del old["task"]["r_success_pitch_margin_deg"]                    # an actor from before the key
    zero = copy.deepcopy(cfg)
    zero["task"]["r_success_pitch_margin_deg"] = 0.0
    assert config_hash(zero) == raw(old)                             # 0 leaves the hash as it was
    m3 = copy.deepcopy(cfg)
    m3["task"]["r_success_pitch_margin_deg"] = 3.0
    assert config_hash(m3) == raw(m3) != raw(old)
    m5 = copy.deepcopy(cfg)
    m5["task"]["r_success_pitch_margin_deg"] = 5.0
    m3_dr = copy.deepcopy(m3)
    m3_dr["randomization"]["enabled"] = 1
    for config in (zero, m3):
        assert hash_matches(raw(old), config)
        assert hash_matches(raw(m3), config) == (config is m3)
        assert hash_matches(raw(m3), config, trained_margin_deg=3.0)
        assert hash_matches(raw(m3_dr), config, trained_margin_deg=3.0)
        assert not hash_matches(raw(m5), config)
        assert hash_matches(raw(m5), config, trained_margin_deg=5.0)
        other = copy.deepcopy(m3)
        other["paper"]["reward"]["R_zone"] = 1000.0
        assert not hash_matches(raw(other), config, trained_margin_deg=3.0)


def test_which_cards_count_as_randomised_and_configs_without_the_sections(cfg):
    """trained_randomized (cards from before `trained_with`): an actor trained on this config with
    or without the margin is not randomised, one trained with the section on is; a config whose
    randomisation is on still runs actors trained without it; configs lacking the sections work."""
    import hashlib
    import json
    from lhd_loading_ros.task.config import hash_matches, trained_randomized

    def raw(c):
        c = {k: v for k, v in c.items() if k != "randomization" or c["randomization"]["enabled"]}
        c = without_unit_gains(c)
        if "task" in c and not c["task"].get("r_success_pitch_margin_deg", 0.0):
            c = {**c, "task": {k: v for k, v in c["task"].items() if k != "r_success_pitch_margin_deg"}}
        if "task" in c:      # the tilt penalty off: its keys out
            c = {**c, "task": {k: v for k, v in c["task"].items() if k not in ("r_tilt_per_deg", "r_tilt_free_deg", "r_tilt_ramp_after_success", "r_tilt_ramp_steps", "r_tilt_ramp_pitch_margin", "midgoal_from_pile", "reward_zones_from_pile", "r_success_mass_margin_kg")}}
        if "training" in c:  # how the critic learned: never in it
            c = {**c, "training": {k: v for k, v in c["training"].items() if k not in NEVER_HASHED}}
        return hashlib.sha256(json.dumps(c, sort_keys=True).encode()).hexdigest()[:16]
    m0 = copy.deepcopy(cfg)
    m0["task"]["r_success_pitch_margin_deg"] = 0.0
    m3 = copy.deepcopy(cfg)
    m3["task"]["r_success_pitch_margin_deg"] = 3.0
    dr0 = copy.deepcopy(m0)
    dr0["randomization"]["enabled"] = 1
    for config in (m0, m3, dr0):
        assert not trained_randomized(raw(m0), config)          # e.g. policies/rld_paper, rlc
        assert not trained_randomized(raw(m3), config, 3.0)
        assert trained_randomized(raw(dr0), config)             # policies/rld_dr
        assert hash_matches(raw(m0), config) and hash_matches(raw(dr0), config)
    no_sections = {k: v for k, v in cfg.items() if k not in ("randomization", "task")}
    assert hash_matches(raw(no_sections), no_sections) and not trained_randomized(raw(no_sections), no_sections)
    assert not hash_matches(raw(m0), no_sections)


def test_a_card_s_trained_with_margin_is_honoured_by_the_policy_loader(cfg, tmp_path):
    """Policy.config_matches: an actor trained with a 5 deg margin matches this config only through
    the margin its card names (trained_with); a card naming nothing, or a wrong type, does not."""
    import json
    import shutil
    from pathlib import Path

    from lhd_loading_ros.policy.actor_file import load_policy, seal_card
    m5 = copy.deepcopy(cfg)
    m5["task"]["r_success_pitch_margin_deg"] = 5.0
    d = tmp_path / "p"
    shutil.copytree(Path(__file__).resolve().parents[2] / "policies" / "rld", d)
    meta = json.loads((d / "policy.json").read_text())
    for trained_with, expected in (({"r_success_pitch_margin_deg": 5.0, "randomize": False}, True),
                                   (None, False), ({"r_success_pitch_margin_deg": "5"}, False)):
        meta["config_hash"] = config_hash(m5)
        if trained_with is None:
            meta.pop("trained_with", None)
        else:
            meta["trained_with"] = trained_with
        (d / "policy.json").write_text(json.dumps(meta))
        seal_card(d)                                    # a card exported so, not one edited after export
        assert load_policy(d).config_matches(cfg) is expected, trained_with
