"""The slope curriculum (training.slope_curriculum; learning/curriculum.py): the draw's
probabilities by hand, the window, the uniform share, the draw's frequencies against its
probabilities, the bins' edges, state round trips and refusals; a short real run whose every
training pile has the slope the curriculum drew on the episode's seed, from a state planted in
the checkpoint and carried on through a resume; the config hash it never enters."""
PARALLEL_SAFE = True

import copy
import csv
import json
import math

import numpy as np
import pytest
import torch

from lhd_loading_ros.learning.curriculum import CurriculumConfig, SlopeCurriculum
from lhd_loading_ros.task.config import config_hash, validate


def test_probabilities_by_hand_window_and_uniform_share():
    c = SlopeCurriculum(15.0, 30.0, CurriculumConfig(bins=3, window=4, uniform=0.5))
    assert c.edges.tolist() == [15.0, 20.0, 25.0, 30.0]
    # nothing seen: every bin counts as failing -> uniform
    assert c.probabilities() == pytest.approx([1 / 3] * 3)
    for ok in (False, False, False, True):      # bin 0 [15, 20): 3 of 4 failed
        c.record(16.0, ok)
    for ok in (True, True):                     # bin 1 [20, 25): none failed
        c.record(20.0, ok)                      # (20 is bin 1's lower edge)
    # bin 2 [25, 30] unseen: 1. f = (0.75, 0, 1), sum 1.75
    # p = 0.5 / 3 + 0.5 f / 1.75 = (0.1667 + 0.2143, 0.1667, 0.1667 + 0.2857)
    assert c.failure_rates() == pytest.approx([0.75, 0.0, 1.0])
    assert c.probabilities() == pytest.approx([0.380952, 0.166667, 0.452381], abs=1e-6)
    assert c.probabilities().sum() == pytest.approx(1.0)
    # the window: four more successes push bin 0's failures out
    for _ in range(4):
        c.record(19.99, True)
    for _ in range(3):
        c.record(30.0, True)                    # the top edge belongs to the last bin
    assert c.failure_rates() == pytest.approx([0.0, 0.0, 0.0])
    assert c.probabilities() == pytest.approx([1 / 3] * 3)     # nothing fails: uniform
    # a small uniform share: the failing bin takes nearly all, the others keep u / B
    d = SlopeCurriculum(15.0, 30.0, CurriculumConfig(bins=3, window=10, uniform=0.03))
    d.record(15.0, False)
    d.record(22.0, True)
    d.record(26.0, True)
    assert d.probabilities() == pytest.approx([0.01 + 0.97, 0.01, 0.01])


def test_draw_frequencies_follow_the_probabilities_within_the_bins():
    c = SlopeCurriculum(15.0, 30.0, CurriculumConfig(bins=6, window=50, uniform=0.5))
    for k in range(6):                          # only the shallowest bin fails
        for _ in range(50):
            c.record(15.0 + 2.5 * k + 1.0, k != 0)
    p = c.probabilities()
    assert p[0] == pytest.approx(0.5 / 6 + 0.5) and p[1:] == pytest.approx([0.5 / 6] * 5)
    rng = np.random.default_rng(3)
    n = 20000
    s = np.array([c.draw(rng) for _ in range(n)])
    assert ((15.0 <= s) & (s <= 30.0)).all()
    counts = np.histogram(s, bins=c.edges)[0]
    # binomial: each count within 4 sd of n p
    sd = np.sqrt(n * p * (1 - p))
    assert (np.abs(counts - n * p) < 4 * sd).all(), (counts, n * p)
    # uniform within a bin: the shallowest bin's draws fill [15, 17.5) evenly (halves within 4 sd)
    low = s[s < 17.5]
    half = np.sum(low < 16.25)
    assert abs(half - len(low) / 2) < 4 * math.sqrt(len(low) / 4)


def test_refusals_and_state_round_trip():
    with pytest.raises(ValueError, match="lo < hi"):
        SlopeCurriculum(30.0, 15.0, CurriculumConfig())
    for u in (1.5, 0.0):          # 0 would never draw a bin again once it succeeds: never measured again
        with pytest.raises(ValueError, match="uniform"):
            SlopeCurriculum(15.0, 30.0, CurriculumConfig(uniform=u))
    c = SlopeCurriculum(15.0, 30.0, CurriculumConfig(bins=6, window=3))
    with pytest.raises(ValueError, match="outside the curriculum's range"):
        c.record(10.0, True)
    for a, ok in ((15.5, False), (15.6, True), (29.0, True), (15.7, False), (15.8, False)):
        c.record(a, ok)
    st = json.loads(json.dumps(c.state_dict()))
    d = SlopeCurriculum(15.0, 30.0, CurriculumConfig(bins=6, window=3))
    d.load_state_dict(st)
    assert d.probabilities() == pytest.approx(c.probabilities())
    assert [list(r) for r in d.recent] == [[True, False, False], [], [], [], [], [True]]   # window 3
    with pytest.raises(ValueError, match="slope_curriculum"):
        SlopeCurriculum(15.0, 30.0, CurriculumConfig(bins=5, window=3)).load_state_dict(st)


def small(cfg, on=1):
    c = copy.deepcopy(cfg)
    c["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 150, "checkpoint_every": 150,
                          "hidden_sizes": [32, 32], "slope_curriculum": on, "slope_curriculum_bins": 3,
                          "slope_curriculum_window": 5, "slope_curriculum_uniform": 0.2})
    return c


def test_config_hash_and_validation(cfg):
    assert config_hash(small(cfg, 1)) == config_hash(small(cfg, 0))
    on = copy.deepcopy(cfg)
    on["training"].update({"slope_curriculum": 1, "slope_curriculum_bins": 4, "slope_curriculum_window": 7,
                           "slope_curriculum_uniform": 0.3})
    assert config_hash(validate(on)) == config_hash(cfg)
    bad = copy.deepcopy(cfg)
    bad["training"]["slope_curriculum_uniform"] = 2.0
    with pytest.raises(ValueError, match="slope_curriculum_uniform"):
        validate(bad)
    # a parameter file written before these keys (and twin_critics) existed still loads: they are
    # filled with their defaults (off), and the hash is the same
    old = copy.deepcopy(cfg)
    for k in ("twin_critics", "slope_curriculum", "slope_curriculum_bins", "slope_curriculum_window",
              "slope_curriculum_uniform", "lr_final_scale", "lr_decay_from", "demo_share", "demo_crowd_min",
              "demo_crowd_max", "demo_pre_curl", "demo_bc"):
        del old["training"][k]
    old = validate(old)
    assert (old["training"]["twin_critics"], old["training"]["slope_curriculum"], old["training"]["demo_share"]) == (0, 0, 0)
    assert config_hash(old) == config_hash(cfg)
    # any other key is still required
    missing = copy.deepcopy(cfg)
    del missing["training"]["eval_seed"]
    with pytest.raises(ValueError, match="missing key 'training.eval_seed'"):
        validate(missing)


def test_a_short_run_draws_its_piles_from_the_curriculum_and_resumes_it(cfg, tmp_path):
    """Every training pile's slope is the curriculum's draw on the episode's seed: replayed here
    episode by episode from episodes.csv, from a state planted in the checkpoint (bins 1 and 2
    succeeding, bin 0 failing), then carried on through the resume with each episode's outcome
    under the paper's success test (episodes.csv `success`)."""
    from lhd_loading_ros.learning.train import episode_seed, train
    from lhd_loading_ros.policy.actor_file import load_policy

    c = small(cfg)
    out = tmp_path / "run"
    train("rld", 5, out, steps=300, config=c, progress=False, log=lambda *a: None)
    meta = load_policy(out / "final").meta
    assert meta["trained_with"]["slope_curriculum"] == {"bins": 3, "window": 5, "uniform": 0.2}
    assert (out / "curriculum.csv").is_file() and "slope_curriculum" in json.loads((out / "run.json").read_text())
    # plant a state: bins 1 and 2 succeeded five times, bin 0 failed five times
    ckpt = out / "checkpoint.pt"
    st = torch.load(ckpt, weights_only=True)
    planted = {"config": {"bins": 3, "window": 5, "uniform": 0.2}, "range_deg": [15.0, 30.0],
               "recent": [[0] * 5, [1] * 5, [1] * 5]}
    st["slope_curriculum"] = json.dumps(planted)
    torch.save(st, ckpt)
    step0 = int(st["step"])
    train("rld", 5, out, steps=1300, config=c, progress=False, log=lambda *a: None)
    with open(out / "episodes.csv") as f:
        rows = [r for r in csv.DictReader(f) if int(r["step"]) > step0]
    # the replay: one environment, episodes in index order; the episode in progress at the
    # checkpoint starts again first (its slope drawn from the planted state)
    ref = SlopeCurriculum(15.0, 30.0, CurriculumConfig(bins=3, window=5, uniform=0.2))
    ref.load_state_dict(planted)
    assert len(rows) >= 6
    shallow = 0
    for r in rows:
        seed_k = episode_seed(5, int(r["episode"]), c["training"]["episode_seed_offset"])
        want = ref.draw(np.random.default_rng([seed_k, 0x5C]))
        assert float(r["alpha_deg"]) == pytest.approx(want, abs=0.006), (r, want)     # the CSV keeps 2 decimals
        shallow += want < 20.0
        # the paper's test, as the learner counted it: a success reached the end zone with >= 20 kg
        assert r["success"] in ("0", "1")
        assert r["success"] == "0" or (r["outcome"] == "success" and float(r["loaded"]) >= 20.0), r
        ref.record(want, r["success"] == "1")
        # r_success (the reward's success term) is paid only to attempts that pass the paper's test with the
        # training margins: >= 20 kg + the mass margin, never to a failure
        assert float(r["r_success"]) >= 0.0
        if float(r["r_success"]) > 0.0:
            assert r["success"] == "1" and float(r["loaded"]) >= 20.0 + c["task"]["r_success_mass_margin_kg"], r
    # with bin 0 alone failing, it held 0.2 / 3 + 0.8 = 0.87 of the first draws
    assert shallow >= 3
    # the checkpoint holds the state after the last finished episode (the run ended on it)
    st = torch.load(ckpt, weights_only=True)
    assert json.loads(st["slope_curriculum"]) == json.loads(json.dumps(ref.state_dict()))
    with pytest.raises(ValueError, match="slope_curriculum"):
        train("rld", 5, out, steps=1500, config=small(cfg, 0), progress=False, log=lambda *a: None)


def test_a_resumed_run_of_the_older_episode_layout_gets_the_success_column(tmp_path):
    """episodes.csv of a run written before the `success` column: the resume's truncation
    rewrites it with the new header (blank in the old rows), so appended rows line up; a file
    truncated to no rows keeps its header for the next append."""
    from lhd_loading_ros.learning.train import EPISODE_FIELDS, _append_csv, _truncate_csv

    old = [k for k in EPISODE_FIELDS if k != "success"]
    path = tmp_path / "episodes.csv"
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=old)
        w.writeheader()
        for k, step in enumerate((100, 250, 400)):
            w.writerow({**{c: "x" for c in old}, "episode": k, "step": step})
    _truncate_csv(path, "step", 300, EPISODE_FIELDS)
    _append_csv(path, EPISODE_FIELDS, {**{c: "y" for c in EPISODE_FIELDS}, "episode": 9, "step": 420, "success": 1})
    rows = list(csv.DictReader(open(path)))
    assert [r["step"] for r in rows] == ["100", "250", "420"]
    assert [r["success"] for r in rows] == ["", "", "1"] and rows[2]["source"] == "y"
    _truncate_csv(path, "step", 50, EPISODE_FIELDS)
    assert open(path).read().strip() == ",".join(EPISODE_FIELDS)
    _append_csv(path, EPISODE_FIELDS, {"episode": 0, "step": 60})
    assert list(csv.DictReader(open(path)))[0]["step"] == "60"


def test_the_sim_nodes_draw_their_own_piles_so_the_curriculum_is_refused_there(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train

    with pytest.raises(ValueError, match="slope_curriculum = 1 .* in-process"):
        train("rld", 0, tmp_path / "r", steps=10, config=small(cfg), env_kind="ros", namespaces=["/sim0"],
              progress=False, log=lambda *a: None)


def test_the_reward_test_counts_what_r_success_pays():
    """training.slope_curriculum_reward_test: with it a bin whose attempts pass the paper's test without
    earning r_success (a 10 deg pile ended with 21 kg under a 4 kg mass margin) still counts as failing,
    and its share of the draw is that of a failing bin, by hand; its settings resume only with it."""
    paper = CurriculumConfig(bins=2, window=4, uniform=0.5)
    reward = CurriculumConfig(bins=2, window=4, uniform=0.5, reward_test=1)
    assert CurriculumConfig.from_training({"slope_curriculum": 1, "slope_curriculum_bins": 2, "slope_curriculum_window": 4,
                                           "slope_curriculum_reward_test": 1}) == reward
    assert paper.to_dict() == {"bins": 2, "window": 4, "uniform": 0.5}          # as every run before it wrote
    assert reward.to_dict() == {**paper.to_dict(), "reward_test": 1}
    # (paper test passed, r_success paid): only both together are a success on the reward's test
    assert [paper.counts_success(p, r) for p, r in ((True, 0.0), (True, 900.0), (False, 0.0))] == [True, True, False]
    assert [reward.counts_success(p, r) for p, r in ((True, 0.0), (True, 900.0), (False, 0.0))] == [False, True, False]
    for cfg_, want in ((paper, [0.5, 0.5]), (reward, [0.75, 0.25])):
        c = SlopeCurriculum(10.0, 40.0, cfg_)
        for _ in range(4):
            c.record(12.0, cfg_.counts_success(True, 0.0))       # shallow: 21 kg, paper's test passed, no r_success
            c.record(30.0, cfg_.counts_success(True, 1100.0))    # steep: both
        # paper: no bin fails -> uniform; reward: f = (1, 0) -> 0.5 / 2 + 0.5 = 0.75 on the shallow bin
        assert c.probabilities() == pytest.approx(want)
    with pytest.raises(ValueError, match="resume with the same"):
        SlopeCurriculum(10.0, 40.0, reward).load_state_dict(SlopeCurriculum(10.0, 40.0, paper).state_dict())


def test_the_class_defaults_are_the_config_defaults():
    """One set of defaults: a training section without the keys gives what config.OPTIONAL_DEFAULTS fills in."""
    from lhd_loading_ros.task.config import OPTIONAL_DEFAULTS

    c = CurriculumConfig.from_training({"slope_curriculum": 1})
    assert c.to_dict() == {k: OPTIONAL_DEFAULTS[("training", f"slope_curriculum_{k}")] for k in ("bins", "window", "uniform")}
