"""An actor trained before a later simulator change (task.config.SIM_CHANGES: keys added to the
physics, not to what the actor sees or commands) is recognised as such, with a note, instead of
the "another parameter file" warning; any other difference is still a mismatch."""
import copy
import hashlib
import json

import pytest

from lhd_loading_ros.policy.actor_file import default_policy_dir, load_policy
from lhd_loading_ros.task import config as config_mod
from lhd_loading_ros.task.config import (config_hash, hash_matches, load_config, sim_change_note,
                                       trained_randomized)


@pytest.fixture(scope="module")
def cfg():
    return load_config()


def _raw(c):
    """The hash by its definition, written out here (randomisation off, margin 3 kept, tilt off,
    the tilt penalty's training schedule, training.twin_critics and the slope curriculum never in it,
    machine.rear_differential only when 1, sim.attack_min_depth only when > 0)."""
    c = {k: v for k, v in c.items() if k != "randomization"}
    if c["machine"].get("rear_differential", 0) == 0:
        c["machine"] = {k: v for k, v in c["machine"].items() if k != "rear_differential"}
    if c["task"].get("bucket_fill_factor", 0.0) == 0.0:   # no fill factor, the static heap (2026-12-02): out at 0
        c["task"] = {k: v for k, v in c["task"].items() if k != "bucket_fill_factor"}
    if c["sim"].get("attack_min_depth", 0.0) == 0.0:      # a stalled drive an error (2026-11-29): out at 0
        c["sim"] = {k: v for k, v in c["sim"].items() if k != "attack_min_depth"}
    c["task"] = {k: v for k, v in c["task"].items() if k not in ("r_tilt_per_deg", "r_tilt_free_deg",
                                                                 "r_tilt_ramp_after_success", "r_tilt_ramp_steps",
                                                                 "r_tilt_ramp_pitch_margin", "midgoal_from_pile",
                                                                 "reward_zones_from_pile", "r_success_mass_margin_kg")}
    c["training"] = {k: v for k, v in c["training"].items()
                     if k not in ("twin_critics", "slope_curriculum", "slope_curriculum_bins", "slope_curriculum_window",
                                  "slope_curriculum_uniform", "slope_curriculum_reward_test", "lr_final_scale", "lr_decay_from",
                                  "demo_share", "demo_crowd_min", "demo_crowd_max", "demo_pre_curl", "demo_bc",
                                  "demo_until_step", "critic_huber", "actor_preact_l2", "demo_q_lower_bound", "noise_after_decay", "demo_bc_return_filter",
                                  "demo_told_zones", "demo_end_zone_stop", "demo_push_curl", "demo_late_lift", "demo_told_high", "demo_failing_share",
                                  "demo_drift_confirm", "demo_where_teacher_wins",
                                  "episode_seed_offset")}
    return hashlib.sha256(json.dumps(c, sort_keys=True).encode()).hexdigest()[:16]


def _before_the_wedge(cfg):
    """The config of an actor trained before the wedge change (2026-11-26), hence also before
    the rear differential (the same day, later)."""
    before = _before_the_fill(cfg)
    del before["pile"]["fee_wedge_by_motion"], before["pile"]["fee_wedge_tau"]
    del before["machine"]["rear_differential"]
    return before


def _before_the_fill(cfg):
    """The config of an actor trained before the fill factor (2026-12-02): no task.bucket_fill_factor."""
    before = copy.deepcopy(cfg)
    before["task"].pop("bucket_fill_factor", None)
    return before


def test_an_actor_from_before_the_wedge_change_is_recognised(cfg):
    before = _before_the_wedge(cfg)
    h_before = _raw(before)
    assert not hash_matches(h_before, cfg)                       # strictly another config ...
    note = sim_change_note(h_before, cfg)
    assert note is not None and "fee_wedge_by_motion" in note    # ... named as the simulator before the change
    assert "rear_differential" in note                           # ... and before the later one
    assert sim_change_note(config_hash(cfg), cfg) is None        # trained on this one: nothing to say
    assert sim_change_note("0123456789abcdef", cfg) is None
    assert sim_change_note(None, cfg) is None
    other = copy.deepcopy(before)
    other["paper"]["reward"]["R_zone"] = 1000.0                  # another change besides: still a mismatch
    assert sim_change_note(_raw(other), cfg) is None
    half = copy.deepcopy(cfg)
    del half["pile"]["fee_wedge_tau"], half["machine"]["rear_differential"]   # one of the wedge's keys only
    assert sim_change_note(_raw(half), cfg) is None


def test_with_the_differential_off_only_the_wedge_is_named(cfg):
    """A config that keeps a motor per rear wheel (rear_differential: 0, the drive before that
    change) differs from a pre-wedge card only by the wedge: the note names the wedge alone."""
    four = copy.deepcopy(cfg)
    four["machine"]["rear_differential"] = 0
    note = sim_change_note(_raw(_before_the_wedge(cfg)), four)
    assert note is not None and "fee_wedge_by_motion" in note and "rear_differential" not in note


def test_an_actor_from_before_the_rear_differential_is_recognised(cfg):
    """Trained after the wedge change, with a motor on each rear wheel (rear_differential 0, or a
    parameter file without the key: the same hash)."""
    four = _before_the_fill(cfg)
    four["machine"]["rear_differential"] = 0
    legacy = _before_the_fill(cfg)
    del legacy["machine"]["rear_differential"]
    assert _raw(four) == _raw(legacy) == config_hash(four) == config_hash(legacy)
    note = sim_change_note(_raw(four), cfg)
    assert note is not None and "rear_differential" in note and "fee_wedge" not in note
    assert sim_change_note(_raw(four), four) is None              # on its own drive: nothing to say


def test_an_actor_between_two_changes_is_recognised(cfg, monkeypatch):
    """With a second, later change listed, an actor trained between the two (its config lacks only
    the later change's key) and one trained before both are each recognised, naming what changed
    since: the changes are undone newest first."""
    cfg2 = copy.deepcopy(cfg)
    cfg2["pile"]["later_key"] = 1
    monkeypatch.setattr(config_mod, "SIM_CHANGES", config_mod.SIM_CHANGES + (
        ("pile", ("later_key",), "2099-01-01", "no later key"),))
    between = copy.deepcopy(cfg)                                 # trained after the listed changes
    before = _before_the_wedge(cfg)
    n_between, n_before = config_mod.sim_change_note(_raw(between), cfg2), config_mod.sim_change_note(_raw(before), cfg2)
    assert n_between is not None and "later_key" in n_between and "fee_wedge" not in n_between
    assert n_before is not None and "later_key" in n_before and "fee_wedge" in n_before


def test_a_randomised_card_from_before_the_change_is_still_randomised(cfg):
    """lhd ship writes whether an actor was trained with domain randomisation from its hash: an
    actor trained randomised before the change keeps that reading (policies/rld_dr)."""
    pol = load_policy(default_policy_dir("rld_dr"))
    assert trained_randomized(pol.meta["config_hash"], cfg)
    assert not trained_randomized(load_policy(default_policy_dir("rld")).meta["config_hash"], cfg)


def test_the_shipped_actors_run_on_the_config(cfg):
    """Every shipped card names this config, either as it is or as it was before a listed
    simulator change (then with the note)."""
    for v in ("rld", "rlc", "rld_paper", "rld_dr", "rld_margin", "rld_tilt", "rld_dr_ramp", "rld_dr_midgoal"):
        pol = load_policy(default_policy_dir(v))
        assert pol.config_matches(cfg), v
        margin, tilt = pol._trained_with()
        if not hash_matches(pol.meta["config_hash"], cfg, margin, tilt):
            note = pol.sim_change_note(cfg)
            assert note is not None and any(date in note for _, _, date, _ in config_mod.SIM_CHANGES), v
            assert "bucket_fill_factor" in note, v       # every one of them trained on the static heap


def test_an_actor_from_before_the_fill_factor_is_recognised(cfg):
    """Trained on the static heap (no task.bucket_fill_factor, or 0: the same hash) and run on a config with
    the handbook's fill factor: recognised, the note naming the fill factor and nothing older."""
    filled = copy.deepcopy(cfg)
    filled["task"]["bucket_fill_factor"] = 0.875
    static = copy.deepcopy(cfg)
    static["task"]["bucket_fill_factor"] = 0.0
    legacy = copy.deepcopy(cfg)
    legacy["task"].pop("bucket_fill_factor", None)
    assert _raw(static) == _raw(legacy) == config_hash(static) == config_hash(legacy)
    assert config_hash(filled) == _raw(filled) != config_hash(static)
    note = sim_change_note(_raw(legacy), filled)
    assert note is not None and "bucket_fill_factor" in note and "2026-12-02" in note
    assert "fee_wedge" not in note and "rear_differential" not in note
    assert sim_change_note(_raw(filled), filled) is None          # trained on it: nothing to say
    other = copy.deepcopy(legacy)
    other["pile"]["density_min"] = 1700.0                         # another change besides: still a mismatch
    assert sim_change_note(_raw(other), filled) is None
