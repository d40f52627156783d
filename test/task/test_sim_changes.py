"""An actor trained before a later simulator change (task.config.SIM_CHANGES: keys added to the
physics, not to what the actor sees or commands) is recognised as such, with a note, instead of
the "another parameter file" warning; any other difference is still a mismatch."""
import copy
import hashlib
import json

import pytest

from lhd_loading_ros.policy.actor_file import default_policy_dir, load_policy
from lhd_loading_ros.task.config import config_hash, hash_matches, load_config, sim_change_note


@pytest.fixture(scope="module")
def cfg():
    return load_config()


def _raw(c):
    """The hash by its definition, written out here (randomisation off, margin 3 kept, tilt off)."""
    c = {k: v for k, v in c.items() if k != "randomization"}
    c["task"] = {k: v for k, v in c["task"].items() if k not in ("r_tilt_per_deg", "r_tilt_free_deg")}
    return hashlib.sha256(json.dumps(c, sort_keys=True).encode()).hexdigest()[:16]


def test_an_actor_from_before_the_wedge_change_is_recognised(cfg):
    before = copy.deepcopy(cfg)
    del before["pile"]["fee_wedge_by_motion"], before["pile"]["fee_wedge_tau"]
    h_before = _raw(before)
    assert not hash_matches(h_before, cfg)                       # strictly another config ...
    note = sim_change_note(h_before, cfg)
    assert note is not None and "fee_wedge_by_motion" in note    # ... named as the simulator before the change
    assert sim_change_note(config_hash(cfg), cfg) is None        # trained on this one: nothing to say
    assert sim_change_note("0123456789abcdef", cfg) is None
    assert sim_change_note(None, cfg) is None
    other = copy.deepcopy(before)
    other["paper"]["reward"]["R_zone"] = 1000.0                  # another change besides: still a mismatch
    assert sim_change_note(_raw(other), cfg) is None
    half = copy.deepcopy(cfg)
    del half["pile"]["fee_wedge_tau"]                            # only one of the change's keys removed
    assert sim_change_note(_raw(half), cfg) is None


def test_the_shipped_main_actor_runs_on_the_config_with_the_note(cfg):
    pol = load_policy(default_policy_dir("rld"))
    assert pol.config_matches(cfg)
    note = pol.sim_change_note(cfg)
    assert note is not None and "2026-11-26" in note
