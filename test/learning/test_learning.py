"""DDPG pieces checked against PyTorch's own autograd and Adam, the paper's noise schedule,
replay semantics (truncation is not terminal), export fidelity, and a short real training
run with checkpoint and resume."""
PARALLEL_SAFE = True   # command-line runs that only compute (lhd eval, lhd ship) (test/conftest.py)

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig, OUNoise, ReplayBuffer, noise_scale
from lhd_loading_ros.learning.export import export_actor
from lhd_loading_ros.learning.mlp import FlatAdam, FlatMlp
from lhd_loading_ros.learning.report import bootstrap_ci, iqm, plot_curves, summarize
from lhd_loading_ros.learning.runner import parse_seeds
from lhd_loading_ros.policy.actor_file import PolicyFileError, load_policy

EXPORT_ATOL = 1e-5   # exported numpy actor vs in-memory torch actor (float32 both; BLAS summation order differs)


def small_cfg(cfg, **training):
    cfg["training"].update({"learning_starts": 256, "eval_episodes": 4, "eval_every": 150,
                            "checkpoint_every": 150, "hidden_sizes": [32, 32], **training})
    return cfg


@pytest.mark.parametrize("out_act", ["tanh", "identity"])
def test_flat_mlp_gradients_match_autograd(out_act):
    g = torch.Generator().manual_seed(1)
    net = FlatMlp([15, 24, 16, 3], out_act, generator=g)
    seq = net.to_sequential()
    x = torch.randn(64, 15, generator=g)
    dy = torch.randn(64, 3, generator=g)
    y, cache = net.forward(x.clone())
    xr = x.clone().requires_grad_(True)
    yr = seq(xr)
    torch.testing.assert_close(y, yr.detach(), rtol=1e-6, atol=1e-6)
    dx = net.backward(cache, dy, weight_grads=True, input_grad=True)
    yr.backward(dy)
    torch.testing.assert_close(dx, xr.grad, rtol=1e-5, atol=1e-6)
    lins = [m for m in seq if isinstance(m, torch.nn.Linear)]
    for j, lin in enumerate(lins):
        torch.testing.assert_close(net.gW[j], lin.weight.grad, rtol=1e-5, atol=1e-6)
        torch.testing.assert_close(net.gb[j], lin.bias.grad, rtol=1e-5, atol=1e-6)


def test_flat_adam_matches_torch_adam():
    g = torch.Generator().manual_seed(2)
    net = FlatMlp([5, 8, 2], "identity", generator=g)
    seq = net.to_sequential()
    opt_ref = torch.optim.Adam(seq.parameters(), lr=1e-3)
    opt = FlatAdam(net, lr=1e-3)
    for _ in range(5):
        x = torch.randn(16, 5, generator=g)
        y, cache = net.forward(x)
        net.backward(cache, 2 * y / y.numel())
        opt.step()
        opt_ref.zero_grad()
        (seq(x) ** 2).mean().backward()
        opt_ref.step()
    ref = torch.cat([p.detach().reshape(-1) for p in seq.parameters()])
    torch.testing.assert_close(net.flat, ref, rtol=1e-5, atol=1e-6)


def reference_update(actor, critic, actor_t, critic_t, oa, r, nd, o2, cfg):
    """A DDPG update written with autograd and torch.optim.Adam (CleanRL's ddpg_continuous_action)."""
    with torch.no_grad():
        y = cfg.reward_scale * r + cfg.gamma * nd * critic_t(torch.cat([o2, actor_t(o2)], 1))
    qf_loss = ((critic(oa) - y) ** 2).mean()
    critic.opt.zero_grad()
    qf_loss.backward()
    critic.opt.step()
    o = oa[:, :12]
    actor_loss = -critic(torch.cat([o, actor(o)], 1)).mean()
    actor.opt.zero_grad()
    actor_loss.backward()
    actor.opt.step()
    with torch.no_grad():
        for net, tgt in ((actor, actor_t), (critic, critic_t)):
            for p, tp in zip(net.parameters(), tgt.parameters()):
                tp.mul_(1 - cfg.tau).add_(cfg.tau * p)


def test_ddpg_update_matches_autograd_reference(cfg):
    dc = DdpgConfig.from_config(small_cfg(cfg))
    agent = DdpgAgent(dc, seed=3)
    actor, critic = agent.actor.to_sequential(), agent.critic.to_sequential()
    actor_t, critic_t = agent.actor_t.to_sequential(), agent.critic_t.to_sequential()
    actor.opt = torch.optim.Adam(actor.parameters(), lr=dc.actor_lr)
    critic.opt = torch.optim.Adam(critic.parameters(), lr=dc.critic_lr)
    g = torch.Generator().manual_seed(4)
    for _ in range(4):
        oa, o2 = torch.rand(dc.batch_size, 15, generator=g) * 2 - 1, torch.rand(dc.batch_size, 12, generator=g)
        r = torch.randn(dc.batch_size, 1, generator=g) * 500
        nd = (torch.rand(dc.batch_size, 1, generator=g) > 0.2).float()
        agent.update(oa, r, nd, o2)
        reference_update(actor, critic, actor_t, critic_t, oa, r, nd, o2, dc)
    for mine, ref in ((agent.actor, actor), (agent.critic, critic), (agent.actor_t, actor_t), (agent.critic_t, critic_t)):
        torch.testing.assert_close(mine.flat, torch.cat([p.detach().reshape(-1) for p in ref.parameters()]),
                                   rtol=1e-4, atol=1e-5)


def test_truncation_bootstraps_and_termination_does_not(cfg):
    dc = DdpgConfig.from_config(small_cfg(cfg))
    rb = ReplayBuffer(4)
    o = np.arange(12) / 12
    rb.add(o, [0.1, 0.2, 0.3], 5.0, False, o)   # truncated (time limit): not terminal
    rb.add(o, [0.1, 0.2, 0.3], 5.0, True, o)    # success / failure: terminal
    assert rb.data[0, 16] == 1.0 and rb.data[1, 16] == 0.0
    agent = DdpgAgent(dc, seed=0)
    o2 = rb.data[:2, 17:]
    q2 = agent.critic_t(torch.cat([o2, agent.actor_t(o2)], 1))
    y = torch.addcmul(rb.data[:2, 15:16] * dc.reward_scale, rb.data[:2, 16:17], q2, value=dc.gamma)
    assert y[1, 0].item() == pytest.approx(5.0 * dc.reward_scale)
    assert y[0, 0].item() == pytest.approx(5.0 * dc.reward_scale + dc.gamma * q2[0, 0].item())


def test_replay_ring_overwrites_oldest():
    rb = ReplayBuffer(3)
    for k in range(5):
        rb.add(np.full(12, k), np.zeros(3), float(k), False, np.full(12, k))
    assert rb.size == 3 and sorted(rb.data[:, 15].tolist()) == [2.0, 3.0, 4.0]
    oa, r, nd, o2 = rb.sample(7, torch.Generator().manual_seed(0))
    assert oa.shape == (7, 15) and r.shape == (7, 1) and nd.shape == (7, 1) and o2.shape == (7, 12)


def test_noise_schedule_is_the_papers():
    assert noise_scale(0, 250_000, 0.05) == 1.0
    assert noise_scale(125_000, 250_000, 0.05) == pytest.approx(0.525)
    assert noise_scale(250_000, 250_000, 0.05) == pytest.approx(0.05)
    assert noise_scale(300_000, 250_000, 0.05) == pytest.approx(0.05)
    # training.noise_after_decay: the same decay, another factor from its end on
    assert noise_scale(249_999, 250_000, 0.05, 0.2) == noise_scale(249_999, 250_000, 0.05)
    assert noise_scale(250_000, 250_000, 0.05, 0.2) == noise_scale(300_000, 250_000, 0.05, 0.2) == 0.2
    assert noise_scale(10, 0, 0.05, 0.2) == 0.2 and noise_scale(10, 0, 0.05) == 0.05


def test_ou_noise_stationary_spread():
    """Euler-Maruyama OU: stationary variance sigma^2 dt / (1 - (1 - theta dt)^2)."""
    sigma, theta, dt = 0.4, 0.15, 0.2
    n = OUNoise(3, 0.0, sigma, theta, dt, np.random.default_rng(0))
    xs = np.array([n.sample() for _ in range(60_000)])[5000:]
    expected = math.sqrt(sigma**2 * dt / (1 - (1 - theta * dt) ** 2))
    assert xs.std() == pytest.approx(expected, rel=0.06)
    assert abs(xs.mean()) < 0.1
    lag1 = np.corrcoef(xs[:-1, 0], xs[1:, 0])[0, 1]
    assert lag1 == pytest.approx(1 - theta * dt, abs=0.01)   # temporally correlated, as DDPG wants


def test_export_reproduces_in_memory_actor(cfg, tmp_path):
    dc = DdpgConfig.from_config(small_cfg(cfg, hidden_sizes=[64, 64]))
    agent = DdpgAgent(dc, seed=5)
    with torch.no_grad():
        agent.actor.flat.mul_(20.0)     # away from the near-zero initial outputs: saturating actions too
    export_actor(tmp_path / "p", agent.actor, cfg, {"variant": "rlc", "seed": 5, "steps": 0})
    pol = load_policy(tmp_path / "p")
    obs = np.random.default_rng(0).uniform(-1, 1, size=(1000, 12)).astype(np.float32)
    with torch.no_grad():
        ref = agent.actor(torch.from_numpy(obs)).numpy()
    got = pol.actor(obs)
    assert np.abs(got - ref).max() <= EXPORT_ATOL
    assert np.abs(ref).max() > 0.99     # the check covers the saturated range
    single = np.stack([pol.actor(o) for o in obs[:20]])
    assert np.abs(single - ref[:20]).max() <= EXPORT_ATOL
    meta = json.loads((tmp_path / "p" / "policy.json").read_text())
    for key in ("variant", "observation", "action", "filters", "config_hash", "seed", "steps", "architecture"):
        assert key in meta
    assert meta["architecture"]["sizes"] == [12, 64, 64, 3]
    # the card states the slopes the actor was trained on (the nodes refuse others)
    ep = cfg["paper"]["episode"]
    assert meta["trained_ranges"]["slope_deg"] == [ep["alpha_min_deg"], ep["alpha_max_deg"]]


def test_load_policy_rejects_bad_directories(cfg, tmp_path):
    with pytest.raises(PolicyFileError, match="does not exist"):
        load_policy(tmp_path / "nowhere")
    agent = DdpgAgent(DdpgConfig.from_config(small_cfg(cfg)), seed=0)
    d = export_actor(tmp_path / "p", agent.actor, cfg, {"variant": "rld", "seed": 0, "steps": 0})
    w = dict(np.load(d / "actor.npz"))
    w["W0"] = w["W0"] * 2
    np.savez(d / "actor.npz", **w)
    with pytest.raises(PolicyFileError, match="SHA-256"):
        load_policy(d)
    (d / "actor.npz").unlink()
    with pytest.raises(PolicyFileError, match="no actor.npz"):
        load_policy(d)
    d2 = export_actor(tmp_path / "q", agent.actor, cfg, {"variant": "rld", "seed": 0, "steps": 0})
    meta = json.loads((d2 / "policy.json").read_text())
    meta["variant"] = "ppo"
    (d2 / "policy.json").write_text(json.dumps(meta))
    with pytest.raises(PolicyFileError, match="variant"):
        load_policy(d2)


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_short_training_run_logs_exports_and_resumes(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train

    small_cfg(cfg)
    out = tmp_path / "run"
    ev = train("rld", 7, out, steps=300, config=cfg, progress=False, log=lambda *a: None)
    rows = read_csv(out / "evals.csv")
    assert [int(r["step"]) for r in rows] == [150, 300]
    assert set(ev) >= {"ar", "aml", "aff", "asl", "success_rate"}
    for name in ("best", "final"):
        pol = load_policy(out / name)
        assert pol.variant == "rld" and pol.meta["seed"] == 7
    assert load_policy(out / "final").meta["steps"] == 300
    eps = read_csv(out / "episodes.csv")
    assert eps and all(int(e["step"]) <= 300 for e in eps)
    st = torch.load(out / "checkpoint.pt", weights_only=True)
    assert st["step"] == 300 and st["agent"]["updates"] == 300 - 256 + 1
    # resume: the same command with more steps continues from the checkpoint
    logs = []
    train("rld", 7, out, steps=450, config=cfg, progress=False, log=logs.append)
    assert any("resumed" in m and "300" in m for m in logs)
    assert [int(r["step"]) for r in read_csv(out / "evals.csv")] == [150, 300, 450]
    st = torch.load(out / "checkpoint.pt", weights_only=True)
    assert st["step"] == 450 and st["agent"]["updates"] == 450 - 256 + 1
    with pytest.raises(ValueError, match="seed"):
        train("rld", 8, out, steps=500, config=cfg, progress=False)
    # fewer steps than the run has: refused, the final actor untouched; the same steps: complete
    final = (out / "final" / "policy.json").read_text()
    with pytest.raises(ValueError, match="already has 450 steps, more than the 300 asked"):
        train("rld", 7, out, steps=300, config=cfg, progress=False, log=lambda *a: None)
    logs = []
    again = train("rld", 7, out, steps=450, config=cfg, progress=False, log=logs.append)
    assert any("is complete" in m for m in logs) and again["step"] == 450
    assert (out / "final" / "policy.json").read_text() == final
    assert [int(r["step"]) for r in read_csv(out / "evals.csv")] == [150, 300, 450]


def test_training_is_deterministic_for_a_seed(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train

    small_cfg(cfg)
    a = train("rlc", 1, tmp_path / "a", steps=300, config=cfg, progress=False)
    b = train("rlc", 1, tmp_path / "b", steps=300, config=cfg, progress=False)
    assert a["ar"] == b["ar"] and a["aml"] == b["aml"]
    wa = np.load(tmp_path / "a" / "final" / "actor.npz")["W0"]
    wb = np.load(tmp_path / "b" / "final" / "actor.npz")["W0"]
    assert np.array_equal(wa, wb)


def test_iqm_and_bootstrap_by_hand():
    assert iqm([1, 2, 3, 4, 100, 6, 7, 8]) == pytest.approx(np.mean([3, 4, 6, 7]))
    assert iqm([5.0, 1.0, 3.0]) == pytest.approx(3.0)
    lo, hi = bootstrap_ci([1.0, 2.0, 3.0, 4.0, 5.0])
    assert 1.0 <= lo <= 3.0 <= hi <= 5.0
    assert bootstrap_ci([2.0, 2.0, 2.0]) == (2.0, 2.0)


def test_report_summary_and_plot(tmp_path):
    fields = ["step", "ar", "aml", "aff", "asl", "success_rate", "elapsed_s", "front_drift_pct", "rear_drift_pct"]
    dirs = []
    for s, final in enumerate([4.0, 5.0, 4.5]):
        d = tmp_path / f"seed_{s}"
        d.mkdir()
        with open(d / "evals.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(fields)
            w.writerow([10000, 100, 10, 0.3, 1.0, 0.2, 4, 5, 5])
            w.writerow([20000, 900, 30, 1.0, final, 0.9, 4, 5, 5])
        dirs.append(d)
    s = summarize(dirs)
    assert s["metrics"]["asl"]["mean"] == pytest.approx(4.5)
    assert s["metrics"]["asl"]["sd"] == pytest.approx(0.5)
    png = plot_curves({"rld": dirs}, tmp_path / "curves.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_parse_seeds():
    assert parse_seeds("0-4") == [0, 1, 2, 3, 4]
    assert parse_seeds("0,2,5") == [0, 2, 5]
    assert parse_seeds("3") == [3]
    for bad in ("4-0", "a", "1,1", "-1"):
        with pytest.raises(ValueError, match="seeds"):
            parse_seeds(bad)


def test_lhd_eval_json_has_the_metrics_and_breakdowns(cfg, tmp_path):
    import subprocess
    import sys

    agent = DdpgAgent(DdpgConfig.from_config(small_cfg(cfg)), seed=0)
    export_actor(tmp_path / "p", agent.actor, cfg, {"variant": "rld", "seed": 0, "steps": 0})
    out = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "eval", "--policy", str(tmp_path / "p"),
                          "--episodes", "8", "--json"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout)
    for k in ("ar", "aml", "aff", "asl", "success_rate", "elapsed_s", "front_drift_pct", "rear_drift_pct", "episodes"):
        assert k in res and isinstance(res[k], (int, float))
    assert res["episodes"] == 8
    assert set(res["by_slope"]) == {"15", "20", "25", "30"}
    assert set(res["by_material"]) == {"homogeneous", "nonhomogeneous"}
    assert sum(v["episodes"] for v in res["by_slope"].values()) == 8
    bad = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "eval", "--policy", str(tmp_path / "none")],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 1 and "does not exist" in bad.stderr


def test_ship_picks_a_seed_and_writes_the_model_card(cfg, tmp_path):
    from lhd_loading_ros.learning.ship import ship
    from lhd_loading_ros.learning.train import train

    small_cfg(cfg)
    cfg["task"]["r_success_pitch_margin_deg"] = 3.0        # the card names the training's margins
    cfg["task"]["r_success_mass_margin_kg"] = 4.0
    for s in (0, 1):
        train("rlc", s, tmp_path / "runs" / f"seed_{s}", steps=300, config=cfg, progress=False)
    cfg_path = tmp_path / "cfg.yaml"
    import yaml
    cfg_path.write_text(yaml.safe_dump(cfg))
    res = ship("rlc", tmp_path / "runs", tmp_path / "policies" / "rlc", episodes=4, config=str(cfg_path),
               log=lambda *a: None)
    out = tmp_path / "policies" / "rlc"
    pol = load_policy(out)
    # two seeds: the median is the lower ranked one, its final actor (not a best checkpoint)
    assert pol.variant == "rlc" and res["select"] == "median"
    assert res["shipped_from"].endswith(("seed_0/final", "seed_1/final"))
    src = Path(res["shipped_from"])
    assert (out / "actor.npz").read_bytes() == (src / "actor.npz").read_bytes()
    card = (out / "README.md").read_text()
    assert "| all | 4 |" in card and "training_curves.png" in card and "| seed_1 |" in card
    assert "| tilt [deg] | tilt > 5 deg |" in card
    assert "the median of 2 seeds" in card and card.count("| shipped |") == 1
    assert (out / "training_curves.png").stat().st_size > 10_000
    ev = json.loads((out / "evaluation.json").read_text())
    assert ev["episodes"] == 4
    # the card also shows the actor under domain randomisation and at the placement corners
    assert ev["randomized"]["episodes"] == ev["stress_placement"]["episodes"] == 4
    assert "| randomised |" in card and "| placement corners |" in card
    assert "Trained without domain randomisation" in card
    # the default parameter file scales its observation as training did, but this file differs from it
    # elsewhere (the training's sizes): the card's figures came from it, so it travels with the actor and
    # the card's commands name it, saying the default would also run the actor
    assert (out / "lhd_params.yaml").read_text().count("the figures of its card were computed under this file") == 1
    assert f"--config {out}/lhd_params.yaml" in card and "also runs under it" in card
    assert f"--config {out}/lhd_params.yaml --deploy-filter --seed 2000000`" in card        # every command names it
    # the command reproduces the table: it names the episodes when they are not the default 120 (a review)
    assert f"--config {out}/lhd_params.yaml --episodes 4 --seed 2000000 --randomize --deploy-filter`" in card
    # shipped under the default file itself: nothing is copied, no --config
    from lhd_loading_ros.learning.ship import parameter_file_need
    from lhd_loading_ros.policy.shipped import shipped_config
    from lhd_loading_ros.task.config import load_config as _load

    assert parameter_file_need(load_policy(out), _load(str(shipped_config("lhd_params.yaml")))) == ""
    assert "Trained on piles of 15-30 deg" in card and "gravel piles of 15-30\ndeg" in card
    # RLC's seeds are ranked as the policy node runs them, with the deployment filter: the median of
    # two is the lower of the two by (success, ASL, AR) of evaluations with the filter, done here by hand
    from lhd_loading_ros.learning.evaluate import evaluate as _evaluate
    from lhd_sim_node.env import LhdLoadingEnv as _Env

    keys = {}
    for s_ in (0, 1):
        e = _evaluate(_Env("rlc", cfg, deploy_filter=True), load_policy(tmp_path / "runs" / f"seed_{s_}" / "final").actor,
                      4, 2_000_000, cfg["task"]["bucket_capacity"])
        keys[s_] = (e["success_rate"], e["asl"], e["ar"])
    assert res["shipped_from"].endswith(f"seed_{min(keys, key=keys.get)}/final")
    assert "| success with the filter | ASL with the filter |" in card and "with the deployment filter, as the policy node" in card
    # lhd report --held-out: every seed's final actor under each condition, the same figures as an
    # evaluation of that actor by hand (RLC with the deployment filter, as on the machine)
    from lhd_loading_ros.learning.evaluate import evaluate
    from lhd_loading_ros.learning.report import held_out
    from lhd_sim_node.env import LhdLoadingEnv

    runs = [tmp_path / "runs" / "seed_0", tmp_path / "runs" / "seed_1"]
    h = held_out(runs, ("nominal", "delay"), 4, str(cfg_path))
    by_hand = evaluate(LhdLoadingEnv("rlc", cfg, deploy_filter=True), load_policy(runs[1] / "final").actor, 4,
                       2_000_000, cfg["task"]["bucket_capacity"], breakdown=False, stress="delay")
    assert h["conditions"]["delay"]["aml"]["values"][1] == pytest.approx(by_hand["aml"])
    assert len(h["conditions"]["nominal"]["success_rate"]["values"]) == 2
    # in worker processes (lhd report --jobs): every evaluation is seeded, the same figures in the same order
    h2 = held_out(runs, ("nominal", "delay"), 4, str(cfg_path), jobs=3)
    assert h2["conditions"] == h["conditions"] and h2["runs"] == h["runs"]
    # success per pile slope: the stratified episodes spread evenly over the slopes, so each seed's
    # success is the mean of its per-slope successes
    sb = h["success_by_slope"]["nominal"]
    assert len(sb) == 4 and h2["success_by_slope"] == h["success_by_slope"]
    for i, overall in enumerate(h["conditions"]["nominal"]["success_rate"]["values"]):
        assert np.mean([v["values"][i] for v in sb.values()]) == pytest.approx(overall)
    with pytest.raises(ValueError, match="unknown condition 'windy'"):
        held_out(runs, ("windy",), 4, str(cfg_path))
    # --zones end-zone-node reaches the evaluation through the work item a worker process gets (jobs=1 runs the
    # same function on the same tuple; the pool itself is checked with jobs=3 above)
    h3 = held_out(runs, ("light",), 4, str(cfg_path), zones="end-zone-node")
    by_hand3 = evaluate(LhdLoadingEnv("rlc", cfg, deploy_filter=True, zones_from_estimate=True, zones_nominal_density=True),
                        load_policy(runs[1] / "final").actor, 4, 2_000_000, cfg["task"]["bucket_capacity"],
                        breakdown=False, stress="light")
    assert h3["zones"] == "end-zone-node" and h3["conditions"]["light"]["aml"]["values"][1] == pytest.approx(by_hand3["aml"])
    with pytest.raises(ValueError, match="zones 'lidar'"):
        held_out(runs, ("light",), 4, str(cfg_path), zones="lidar")
    # the node's density set as on the machine (--zones-density): the same figures as that environment by hand
    h4 = held_out(runs[1:], ("light",), 4, str(cfg_path), zones="end-zone-node", zones_density=1550.0)
    by_hand4 = evaluate(LhdLoadingEnv("rlc", cfg, deploy_filter=True, zones_from_estimate=True, zones_nominal_density=True,
                                      zones_density=1550.0),
                        load_policy(runs[1] / "final").actor, 4, 2_000_000, cfg["task"]["bucket_capacity"],
                        breakdown=False, stress="light")
    assert h4["zones_density"] == 1550.0 and h4["conditions"]["light"]["aml"]["values"][0] == pytest.approx(by_hand4["aml"])
    with pytest.raises(ValueError, match="--zones-density 1550 is the end-zone node's density"):
        held_out(runs, ("light",), 4, str(cfg_path), zones_density=1550.0)
    # best-final: the best seed's FINAL actor; the card's tables on piles the choice never saw,
    # the same figures as an evaluation of that actor by hand on the confirmation seed
    res2 = ship("rlc", tmp_path / "runs", tmp_path / "policies" / "best", episodes=4, config=str(cfg_path),
                log=lambda *a: None, select="best-final")
    assert res2["shipped_from"].endswith("/final") and res2["select"] == "best-final"
    card2 = (tmp_path / "policies" / "best" / "README.md").read_text()
    assert "the best of 2 seeds' final actors" in card2 and "--seed 3000000" in card2
    ev2 = json.loads((tmp_path / "policies" / "best" / "evaluation.json").read_text())
    assert ev2["evaluation_seed"] == 3_000_000
    by_hand2 = evaluate(LhdLoadingEnv("rlc", cfg), load_policy(res2["shipped_from"]).actor, 4, 3_000_000,
                        cfg["task"]["bucket_capacity"], breakdown=False)
    assert ev2["aml"] == pytest.approx(by_hand2["aml"]) and ev2["success_rate"] == by_hand2["success_rate"]
    # the training-only settings are on the card: the pitch margin of the config it was trained with
    meta = load_policy(res2["shipped_from"]).meta
    assert meta["trained_with"] == {"randomize": False, "r_success_pitch_margin_deg": 3.0, "r_tilt_per_deg": 0.0,
                                    "r_tilt_free_deg": 3.0, "r_success_mass_margin_kg": 4.0}
    assert "paid only above 43 deg" in card2 and "six documented departures" in card2
    assert "and only from 24 kg (the training's mass margin" in card2
    assert "and a 3 deg pitch margin and a 4 kg mass margin" in card2 and "Trained without domain randomisation." in card2
    assert "--seed 3000000 --randomize" in card2


def test_ship_copies_the_parameter_file_an_actor_needs(cfg, tmp_path, monkeypatch):
    """An actor trained on 10-35 deg piles normalises the slope otherwise than config/lhd_params.yaml
    (15-30): lhd ship copies the parameter file it was shipped with next to it, and the card's
    commands name it, with the recipe (demonstrations, cloning, two critics) and the slope range."""
    import yaml

    from lhd_loading_ros.learning.ship import ship
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.policy.actor_file import PolicyFileError
    from lhd_loading_ros.task.config import load_config

    small_cfg(cfg, twin_critics=1, demo_share=0.4, demo_bc=1.0)
    cfg["paper"]["episode"]["alpha_min_deg"], cfg["paper"]["episode"]["alpha_max_deg"] = 10.0, 35.0
    train("rld", 0, tmp_path / "runs" / "seed_0", steps=300, config=cfg, progress=False)
    cfg_path = tmp_path / "wide.yaml"
    cfg_path.write_text(yaml.safe_dump(cfg))
    logs = []
    ship("rld", tmp_path / "runs", tmp_path / "pol", episodes=2, config=str(cfg_path), log=logs.append)
    out = tmp_path / "pol"
    copied = out / "lhd_params.yaml"
    assert copied.is_file() and copied.read_text().startswith(f"#| The parameter file of the actor in {out} (a copy of {cfg_path}")
    assert f"Pass it with --config {out}/lhd_params.yaml (lhd) or -p config:={out}/lhd_params.yaml" in copied.read_text()
    assert load_config(str(copied)) == load_config(str(cfg_path))
    assert any(m.endswith("lhd_params.yaml: the actor runs only with it") for m in logs)
    pol = load_policy(out)
    pol.check_config(load_config(str(copied)))               # runs under its own file
    with pytest.raises(PolicyFileError, match="10-35 deg|alpha"):
        pol.check_config(load_config(None))                   # and is refused under the default,
    with pytest.raises(PolicyFileError, match=f"shipped with it: --config {out}/lhd_params.yaml"):
        pol.check_config(load_config(None))                   # naming the file that travels with it
    with pytest.raises(PolicyFileError, match="trained on 10-35 deg piles, this file's are 15-30 deg"):
        pol.check_config(load_config(None))                   # and the pile ranges, in degrees
    # shipped again into the same folder, from the copy inside it: read before the folder is replaced,
    # one header (not two), the same parameters
    ship("rld", tmp_path / "runs", out, episodes=2, config=str(copied), log=logs.append)
    again = copied.read_text()
    assert again.count("written by lhd ship") == 1 and load_config(str(copied)) == load_config(str(cfg_path))
    assert (out / "README.md").is_file()
    # the default file is found in the source tree, not through $LHD_CONFIG: with LHD_CONFIG pointing at
    # the actor's own file the copy is still made
    monkeypatch.setenv("LHD_CONFIG", str(cfg_path))
    ship("rld", tmp_path / "runs", tmp_path / "pol2", episodes=2, config=str(cfg_path), log=logs.append)
    assert (tmp_path / "pol2" / "lhd_params.yaml").is_file()
    card = (out / "README.md").read_text()
    assert f"lhd up sim --policy {out} --config {out}/lhd_params.yaml" in card
    assert f"-p config:={out}/lhd_params.yaml" in card and "`lhd_params.yaml` (the parameter file it runs under)" in card
    assert "Trained on piles of 10-35 deg" in card and "gravel piles of 10-35\ndeg" in card
    assert "The evaluations below are on the paper's 15, 20, 25, 30 deg piles (`lhd experiment paper --slopes`" in card
    assert "until the exploration noise's decay ends" in card
    assert ("scripted demonstrations in 40% of the training episodes until the exploration noise's decay ends "
            "with Q-filtered behaviour cloning") in card
    assert "clipped double Q (two critics" in card


def test_ship_selection_median_and_best():
    from lhd_loading_ros.learning.ship import pick

    keys = [((0.75, 3.4, 10.0), "a"), ((1.0, 4.4, 50.0), "b"), ((0.875, 4.1, 30.0), "c"),
            ((0.958, 4.6, 40.0), "d"), ((0.875, 3.9, 20.0), "e")]
    # ranked: a (0.75) < e (0.875, 3.9) < c (0.875, 4.1) < d < b
    assert pick(keys, "median")[1] == "c"
    assert pick(keys, "best")[1] == "b"
    assert pick(keys, "best-final")[1] == "b"
    assert pick(keys[:4], "median")[1] == "c"        # a < c < d < b: the lower middle one
    assert pick(keys[:1], "median")[1] == "a"
    with pytest.raises(ValueError, match="select must be one of"):
        pick(keys, "luckiest")


def test_the_tilt_gate_leaves_prying_seeds_out_of_the_median():
    """lhd ship --max-tilt-rate: seeds whose held-out share of attempts tilting the machine over 5 deg
    exceeds the gate are not candidates; the median is taken over the others (lower middle one)."""
    from pathlib import Path as P

    from lhd_loading_ros.learning.ship import gate_tilt, pick

    def cand(name, success, asl, tilt):
        return ((success, asl, 0.0), P(name), None, {"tilt_over_5deg_rate": tilt})

    cands = [cand("seed_0", 1.0, 4.76, 0.0), cand("seed_1", 1.0, 4.28, 0.32), cand("seed_2", 0.975, 4.03, 0.04),
             cand("seed_3", 1.0, 4.61, 0.01), cand("seed_4", 0.75, 3.74, 0.0)]
    assert pick(cands, "median")[1].name == "seed_1"                 # without the gate: 0.75, 0.975, [1.0 x3 by ASL]
    kept, out = gate_tilt(cands, 0.05)
    assert [c[1].name for c in out] == ["seed_1"] and len(kept) == 4
    assert pick(kept, "median")[1].name == "seed_2"                  # 0.75, [0.975], 1.0/4.61, 1.0/4.76
    assert gate_tilt(cands, None) == (cands, [])
    assert gate_tilt(cands, 0.04)[1] == [cands[1]]                   # at the gate: kept
    with pytest.raises(ValueError, match="every seed lifts the machine's rear"):
        gate_tilt([cands[1], cands[2]], 0.03)
    with pytest.raises(ValueError, match="expected a share in"):
        gate_tilt(cands, 1.5)


def test_a_run_too_short_to_update_says_so(cfg, tmp_path):
    """Fewer steps than training.learning_starts: no update runs, and the actor written is the
    untrained one: said in the log (a review: `lhd train --steps 500` wrote it without a word)."""
    from lhd_loading_ros.learning.train import train

    small_cfg(cfg)                     # learning_starts 256
    lines = []
    train("rld", 0, tmp_path / "run", steps=200, config=cfg, progress=False, log=lines.append)
    assert lines[0] == ("warning: 200 steps are not more than training.learning_starts = 256: no update will run, "
                        "and the actor written is the untrained one"), lines


def test_the_cards_drawn_conditions_are_the_files_ranges():
    """The card's "When the machine differs" names what `lhd eval --randomize` draws under the file it was
    evaluated with (learning/ship.drawn_conditions), not a fixed list: a card of an actor trained with
    actuator gains, starts from rest or rough piles says so, with the file's numbers."""
    import copy

    from lhd_loading_ros.learning.ship import drawn_conditions
    from lhd_loading_ros.task.config import load_config

    cfg = load_config()
    text = drawn_conditions(cfg)
    r = cfg["randomization"]
    assert f"+-{r['slope_error_max_deg']:g} deg" in text and f"cohesion up to {r['cohesion_max']:,.0f} Pa" in text
    assert "commanded" not in text and "from rest" not in text and "rough face" not in text   # all off
    assert "too steep" not in text and "drift flag" not in text
    other = copy.deepcopy(cfg)
    other["randomization"].update(slope_error_max_deg=7.0, cohesion_max=1500.0, drive_gain_min=0.75,
                                  drive_gain_max=1.1, rest_start_share=0.3, surface_sd_max=0.03,
                                  actuator_delay_max_s=0.06, slope_error_high_share=0.25, drift_flag_lag_max_s=0.14)
    text = drawn_conditions(other)
    for part in ("+-7 deg", "0-60 ms actuator dead time", "cohesion up to 1,500 Pa", "wheels at 0.75-1.1 of",
                 "30 % of the attempts from rest", "relief sd up to 3 cm",
                 "the slope error of 25 % of the attempts drawn 3.5-7 deg too steep (the others' from the whole range)",
                 "the drift flag over a control period ending up to 140 ms before the observation (the bridge's window)"):
        assert part in text, (part, text)
    assert "boom and bucket" not in text                 # its gains at 1: not drawn


def test_lhd_eval_zones_of_the_end_zone_node(cfg):
    """`lhd eval --zones end-zone-node`: the figures of the environment whose zones are the end-zone node's
    wedge at the nominal density, computed in this process; on light gravel that end zone lies nearer than
    the pile's own 170 kg, so the shipped actor stops with less than with the pile's zones."""
    import subprocess
    import sys

    from lhd_loading_ros.learning.evaluate import evaluate
    from lhd_loading_ros.policy.actor_file import load_policy
    from lhd_sim_node.env import LhdLoadingEnv

    cmd = [sys.executable, "-m", "lhd_loading_ros.cli.main", "eval", "--policy", "policies/rld", "--stress", "light",
           "--episodes", "8", "--json", "--zones", "end-zone-node"]
    res = json.loads(subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=True).stdout)
    assert res["zones"] == "end-zone-node" and res["zones_density"] == pytest.approx(1880.0)
    pol = load_policy("policies/rld")
    mine, pile = (evaluate(LhdLoadingEnv("rld", cfg, zones_from_estimate=True, zones_nominal_density=nd), pol.actor, 8,
                           2_000_000, cfg["task"]["bucket_capacity"], stress="light") for nd in (True, False))
    assert res["aml"] == pytest.approx(mine["aml"], rel=1e-9)
    assert res["aml"] < pile["aml"] - 1.0


def test_lhd_eval_warns_when_the_end_zone_node_would_publish_no_zones(cfg, capsys):
    """At 500 kg/m^3 the end-zone node's wedge holds m_max = 170 kg only on piles below about 15 deg
    (rho w tan(alpha) L^2 / 2 with L = h / tan(alpha): 500 x 0.4 x 0.68^2 / (2 tan alpha) >= 170 kg needs
    tan(alpha) <= 0.272): it publishes no zones for the 20-30 deg piles, those attempts would not start on
    the machine, and the evaluation, which judges them with the pile's own zones, says so on stderr. At the
    node's default density every pile gets its zones and nothing is said."""
    from lhd_loading_ros.cli.main import main
    from lhd_loading_ros.learning.evaluate import zones_fallback_warning

    tan_limit = 500 * 0.4 * 0.68 ** 2 / (2 * 170)
    assert math.tan(math.radians(15.0)) <= tan_limit < math.tan(math.radians(20.0))     # by hand, as above
    assert main(["eval", "--policy", "policies/rld", "--episodes", "4", "--json", "--zones", "end-zone-node",
                 "--zones-density", "500"]) == 0
    out, err = capsys.readouterr()
    res = json.loads(out)
    # episodes 0-3 are the 15, 20, 25, 30 deg piles: three have no zones from the node
    assert res["zones_from"] == {"wedge at nominal density": 1, "pile, the end-zone node publishes none for the "
                                 "estimate": 3}, res["zones_from"]
    assert "warning: 3 of 4 episodes were judged with the pile's own zones" in err and "500 kg/m^3" in err, err
    assert main(["eval", "--policy", "policies/rld", "--episodes", "4", "--json", "--zones", "end-zone-node"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["zones_from"] == {"wedge at nominal density": 4} and "warning" not in err, err
    assert zones_fallback_warning({"zones_from": {"pile": 2}}) is None
    assert "1 of 3 episodes" in zones_fallback_warning({"zones_from": {"pile": 2, "pile, estimate out of range": 1}})


def test_report_names_runs_that_ended_at_other_steps_or_before_their_plan(tmp_path):
    """A review (2026-11-29, twelfth session): `lhd report` printed "final step 20,000" over one run at 60,000
    and one stopped at 20,000, averaging the two stages without a word."""
    import json

    from lhd_loading_ros.learning.report import format_summary, summarize

    head = "step,ar,aml,aff,asl,success_rate,elapsed_s,front_drift_pct,rear_drift_pct\n"
    for name, last, plan in (("seed_0", 60000, 60000), ("seed_1", 20000, 60000)):
        d = tmp_path / name
        d.mkdir()
        rows = "".join(f"{s},1,20,0.7,1,0.5,4,1,30\n" for s in range(10000, last + 1, 10000))
        (d / "evals.csv").write_text(head + rows)
        (d / "run.json").write_text(json.dumps({"ddpg": {"total_steps": plan}}))
    s = summarize([tmp_path / "seed_0", tmp_path / "seed_1"])
    assert s["final_steps"] == [60000, 20000] and s["planned_steps"] == [60000, 60000]
    text = format_summary("mixed", s)
    assert "last steps 20,000-60,000" in text and "unfinished: seed_1 at 20,000 of 60,000" in text
    same = summarize([tmp_path / "seed_0"])
    assert "final step 60,000" in format_summary("one", same) and "warning" not in format_summary("one", same)
