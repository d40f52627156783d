"""Q-filtered behaviour cloning on the scripted demonstrations (training.demo_bc, DDPGfD):
the replay's demonstration flag, the update against a reference written with autograd and
torch.optim.Adam (the Q-filter evaluated independently), that a batch without demonstrations
updates exactly as plain DDPG, what is refused, and a short real run whose replay flags exactly
the demonstrations' transitions."""
PARALLEL_SAFE = True

import copy
import csv
import dataclasses

import numpy as np
import pytest
import torch

from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig, ReplayBuffer
from lhd_loading_ros.task.config import config_hash, validate


def small_cfg(cfg, **training):
    c = copy.deepcopy(cfg)
    c["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 400, "checkpoint_every": 400,
                          "hidden_sizes": [32, 32], **training})
    return c


def test_the_replay_flags_demonstrations_beside_the_aux_column():
    rb = ReplayBuffer(8, aux=True, demo=True)
    assert rb.width == 2 * 12 + 3 + 2 + 2
    o = np.arange(12) / 12.0
    for k in range(8):
        rb.add(o + k, np.full(3, 0.1 * k), float(k), False, o - k, aux=10.0 * k, demo=k % 3 == 0)
    rb.aux_weight = 0.5
    oa, r, nt, o2, d = rb.sample(64, torch.Generator().manual_seed(0))
    k = oa[:, 12] / 0.1                                    # each row's k, read back from its action
    kk = torch.round(k)
    torch.testing.assert_close(r[:, 0], kk + 0.5 * 10.0 * kk)          # r + w aux: the aux column, not the flag
    torch.testing.assert_close(d[:, 0], (kk % 3 == 0).float())
    torch.testing.assert_close(o2[:, 0], -kk)
    # an aux column and a flag column have the same width: a checkpoint of one never loads into the other
    aux_only, demo_only = ReplayBuffer(8, aux=True), ReplayBuffer(8, demo=True)
    assert aux_only.width == demo_only.width
    aux_only.add(o, np.zeros(3), 0.0, False, o, aux=-7.5)
    with pytest.raises(ValueError, match="holds the tilt term apart .* this run's replay the demonstration flag"):
        demo_only.load_state_dict(aux_only.state_dict())
    with pytest.raises(ValueError, match="holds the demonstration flag .* this run's replay the tilt term apart"):
        aux_only.load_state_dict(demo_only.state_dict())
    # a checkpoint written before the flag existed (no "aux"/"demo" keys): its width says aux or not
    old = {k: v for k, v in aux_only.state_dict().items() if k not in ("aux", "demo")}
    ReplayBuffer(8, aux=True).load_state_dict(old)
    with pytest.raises(ValueError, match="holds the tilt term apart"):
        demo_only.load_state_dict(old)
    both = ReplayBuffer(8, aux=True, demo=True)         # the first flag checkpoints: two extra columns, unnamed
    both.add(o, np.zeros(3), 0.0, False, o, aux=-1.0, demo=True)
    ReplayBuffer(8, aux=True, demo=True).load_state_dict({k: v for k, v in both.state_dict().items()
                                                          if k not in ("aux", "demo")})
    plain = ReplayBuffer(4)
    plain.add(o, np.zeros(3), 0.0, False, o)
    assert len(plain.sample(2, torch.Generator().manual_seed(0))) == 4     # no flag column, no fifth tensor
    with pytest.raises(ValueError, match="no demonstration flag"):
        plain.add(o, np.zeros(3), 0.0, False, o, demo=True)


def reference_update_bc(actor, critic, actor_t, critic_t, oa, r, nd, o2, demo, cfg, w, G=None):
    """DDPG (CleanRL's update) plus DDPGfD's Q-filtered behaviour cloning, with autograd; with G (the
    demonstrations' own returns, unscaled) the return filter in place of the Q-filter."""
    with torch.no_grad():
        y = cfg.reward_scale * r + cfg.gamma * nd * critic_t(torch.cat([o2, actor_t(o2)], 1))
    critic.opt.zero_grad()
    ((critic(oa) - y) ** 2).mean().backward()
    critic.opt.step()
    o, a = oa[:, :12], oa[:, 12:]
    pi = actor(o)
    with torch.no_grad():           # the filter, by the updated critic: the demonstration's action valued higher
        better = critic(oa) if G is None else cfg.reward_scale * G      # ... or its own return higher
        f = demo * (better > critic(torch.cat([o, pi], 1))).float()
    loss = -critic(torch.cat([o, pi], 1)).mean() + w * (f * ((pi - a) ** 2).sum(1, keepdim=True)).sum() / oa.shape[0]
    actor.opt.zero_grad()
    loss.backward()
    actor.opt.step()
    with torch.no_grad():
        for net, tgt in ((actor, actor_t), (critic, critic_t)):
            for p, tp in zip(net.parameters(), tgt.parameters()):
                tp.mul_(1 - cfg.tau).add_(cfg.tau * p)
    return int(f.sum()), int(demo.sum())


@pytest.mark.parametrize("return_filter", [0, 1])
def test_the_update_matches_an_autograd_reference(cfg, return_filter):
    """The update against autograd + torch.optim with the filter evaluated independently: the Q-filter
    (return_filter 0) or f_i = demo_i [reward_scale G_i > Q(o_i, mu(o_i))] (1); the critic's step is the same."""
    dc = dataclasses.replace(DdpgConfig.from_config(small_cfg(cfg)), demo_bc=2.0, batch_size=128,
                             demo_bc_return_filter=return_filter)
    agent = DdpgAgent(dc, seed=5)
    nets = [agent.actor.to_sequential(), agent.critic.to_sequential(), agent.actor_t.to_sequential(),
            agent.critic_t.to_sequential()]
    nets[0].opt = torch.optim.Adam(nets[0].parameters(), lr=dc.actor_lr)
    nets[1].opt = torch.optim.Adam(nets[1].parameters(), lr=dc.critic_lr)
    g = torch.Generator().manual_seed(6)
    passed = rows = 0
    for _ in range(5):
        oa, o2 = torch.rand(dc.batch_size, 15, generator=g) * 2 - 1, torch.rand(dc.batch_size, 12, generator=g)
        r = torch.randn(dc.batch_size, 1, generator=g) * 500
        nd = (torch.rand(dc.batch_size, 1, generator=g) > 0.2).float()
        demo = (torch.rand(dc.batch_size, 1, generator=g) < 0.4).float()
        G = None
        if return_filter:
            G = torch.randn(dc.batch_size, 1, generator=g) * 5.0        # unscaled returns around Q / reward_scale
            G[::7] = -float("inf")                                        # some still unknown
        agent.update(oa, r, nd, o2, demo, G)
        p, n = reference_update_bc(*nets, oa, r, nd, o2, demo, dc, dc.demo_bc, G)
        passed, rows = passed + p, rows + n
        torch.testing.assert_close(agent.actor.flat, torch.cat([q.detach().reshape(-1) for q in nets[0].parameters()]),
                                   rtol=1e-4, atol=1e-5)
    # the filter let some rows through and held others back (so both branches were tested), and
    # the agent's own count of them is the reference's
    assert 0 < passed < rows
    assert (agent.bc_passed, agent.bc_rows) == (passed, rows)


def test_no_demonstration_in_the_batch_is_plain_ddpg(cfg):
    dc = dataclasses.replace(DdpgConfig.from_config(small_cfg(cfg)), demo_bc=5.0)
    a, b = DdpgAgent(dc, seed=1), DdpgAgent(dataclasses.replace(dc, demo_bc=0.0), seed=1)
    g = torch.Generator().manual_seed(2)
    for _ in range(3):
        oa, o2 = torch.rand(dc.batch_size, 15, generator=g), torch.rand(dc.batch_size, 12, generator=g)
        r, nd = torch.randn(dc.batch_size, 1, generator=g), torch.ones(dc.batch_size, 1)
        a.update(oa, r, nd, o2, torch.zeros(dc.batch_size, 1))
        b.update(oa, r, nd, o2)
    assert torch.equal(a.actor.flat, b.actor.flat) and torch.equal(a.critic.flat, b.critic.flat)


def test_behaviour_cloning_needs_demonstrations(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train

    with pytest.raises(ValueError, match="demo_bc = 1 clones .* training.demo_share = 0 gives none"):
        train("rld", 0, tmp_path, steps=10, config=small_cfg(cfg, demo_bc=1.0), resume=False, progress=False)


def test_a_short_run_flags_exactly_the_demonstrations(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.policy.actor_file import load_policy

    c = small_cfg(cfg, demo_share=0.5, demo_bc=1.0)
    logs = []
    train("rld", 3, tmp_path, steps=400, config=c, resume=False, progress=False, log=logs.append)
    with open(tmp_path / "episodes.csv") as f:
        rows = list(csv.DictReader(f))
    demo_steps = sum(int(r["steps"]) for r in rows if r["driver"] != "actor")
    actor_steps = sum(int(r["steps"]) for r in rows if r["driver"] == "actor")
    assert demo_steps > 0 and actor_steps > 0
    st = torch.load(tmp_path / "checkpoint.pt", weights_only=True)
    flags = st["replay"]["data"][:, -1]
    assert set(flags.unique().tolist()) == {0.0, 1.0}
    # every transition of a finished episode is in the replay, and so are the steps of the episode
    # still running at the end, flagged if it is a demonstration (its index follows the last one)
    from lhd_loading_ros.learning.demonstrations import DemoConfig
    from lhd_loading_ros.learning.train import episode_seed

    rest = 400 - demo_steps - actor_steps
    last_is_demo = DemoConfig.from_training(validate(c)["training"]).draw(episode_seed(3, len(rows), c["training"]["episode_seed_offset"]), 0) is not None
    assert [int(r["episode"]) for r in rows] == list(range(len(rows)))
    assert int(flags.sum()) == demo_steps + (rest if last_is_demo else 0)
    assert any("behaviour cloning on" in line for line in logs)
    meta = load_policy(tmp_path / "final").meta
    assert meta["trained_with"]["demo_bc"] == 1.0 and meta["trained_with"]["demonstrations"]["demo_share"] == 0.5
    assert meta["config_hash"] == config_hash(validate(small_cfg(cfg)))      # never in the hash


# ---------------------------------------------------------------- the return filter (demo_bc_return_filter)
def test_the_replay_keeps_a_demonstrations_return_from_each_row():
    gamma = 0.9
    rb = ReplayBuffer(6, aux=True, demo=True, demo_return=True)
    assert rb.width == 2 * 12 + 3 + 2 + 1 + 2 + 1           # aux, G, G_aux, the flag still last
    o = np.zeros(12)
    rows = []
    for k in range(4):                                      # a demonstration of 4 steps: r = k + 1, aux = -k
        t = rb.add(o + k, np.full(3, 0.1 * k), float(k + 1), k == 3, o, aux=-float(k), demo=True)
        rows.append((t, float(k + 1), -float(k)))
    actor_row = rb.add(o + 9, np.full(3, 0.9), 5.0, False, o, aux=0.0, demo=False)
    rb.aux_weight = 0.5
    _, _, _, _, d, g = rb.sample(64, torch.Generator().manual_seed(0))
    assert torch.isinf(g).all() and (g < 0).all()           # nothing known yet: no row can pass the filter
    assert rb.set_demo_return(rows, gamma) == 4
    oa, r, nt, o2, d, g = rb.sample(256, torch.Generator().manual_seed(1))
    k = torch.round(oa[:, 12] / 0.1).long()
    # by hand: G_t = sum_{j >= t} gamma^(j - t) r_j, the same for aux, then G + w G_aux
    rs, auxs = [1.0, 2.0, 3.0, 4.0], [0.0, -1.0, -2.0, -3.0]
    want = {t: sum(gamma ** (j - t) * (rs[j] + 0.5 * auxs[j]) for j in range(t, 4)) for t in range(4)}
    for row in range(256):
        if int(k[row]) == 9:
            assert d[row, 0] == 0.0 and g[row, 0] == -float("inf")     # the actor's row: no return, not cloned
        else:
            assert d[row, 0] == 1.0
            assert abs(float(g[row, 0]) - want[int(k[row])]) < 1e-5
    # a row the ring has overwritten since is skipped, the others written
    rb2 = ReplayBuffer(3, demo=True, demo_return=True)
    tickets = [rb2.add(o, np.zeros(3), 1.0, False, o, demo=True) for _ in range(4)]     # the first is gone
    assert rb2.set_demo_return([(t, 1.0, 0.0) for t in tickets], 1.0) == 3
    assert sorted(rb2.data[:, -2].tolist()) == [1.0, 2.0, 3.0]
    # checkpoints: the same layout loads, the other is refused with the setting's name
    rb3 = ReplayBuffer(6, aux=True, demo=True, demo_return=True)
    rb3.load_state_dict(rb.state_dict())
    assert torch.equal(rb3.data, rb.data) and rb3.added == rb.added == actor_row + 1
    with pytest.raises(ValueError, match="holds the demonstrations' returns.*demo_bc_return_filter"):
        ReplayBuffer(6, aux=True, demo=True).load_state_dict(rb.state_dict())
    with pytest.raises(ValueError, match="does not hold the demonstrations' returns, this run's replay does"):
        rb3.load_state_dict(ReplayBuffer(6, aux=True, demo=True).state_dict())
    with pytest.raises(ValueError, match="needs the demonstration flag"):
        ReplayBuffer(6, demo_return=True)


def test_the_return_filter_needs_behaviour_cloning(cfg):
    from lhd_loading_ros.task.config import ConfigError

    with pytest.raises(ConfigError, match="demo_bc_return_filter = 1 only with training.demo_bc > 0"):
        validate(small_cfg(cfg, demo_bc_return_filter=1, demo_bc=0.0))


def test_a_short_run_writes_each_finished_demonstrations_return(cfg, tmp_path, monkeypatch):
    """A real run with the tilt ramp on (the reward split into a main part and the ramped part) and one
    demonstration aborted by a real MuJoCo fault (a NaN in the velocities, as test_train_abort.py): in the
    checkpoint's replay the rows of every finished demonstration carry their episode's discounted returns
    to its end, main and ramped part apart, summed here from the stored rewards; the actor's rows, the
    aborted demonstration's and the unfinished episode's carry none (-inf); the card names the filter,
    the hash does not."""
    import math

    from lhd_loading_ros.learning.ship import _recipe_note
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.policy.actor_file import load_policy
    from lhd_sim_node.env import LhdLoadingEnv

    c = small_cfg(cfg, demo_share=0.5, demo_bc=1.0, demo_bc_return_filter=1)
    c["task"].update({"r_tilt_per_deg": 10.0, "r_tilt_free_deg": 0.0, "r_tilt_ramp_after_success": 0.5})
    c["training"]["episode_seed_offset"] = 0     # the piles this case was written on: the first episode a long demonstration
    c["task"]["bucket_fill_factor"] = 0.0        # ... on the static heap it was written on (a fuller bucket ends it later)
    calls = {"n": 0}
    real_step = LhdLoadingEnv.step

    def step(self, action):
        calls["n"] += 1
        if calls["n"] == 60 and self.steps > 0:        # the first episode, a demonstration, at its 60th step
            self.sim.data.qvel[0] = math.nan
        return real_step(self, action)

    monkeypatch.setattr(LhdLoadingEnv, "step", step)
    logs = []
    train("rld", 3, tmp_path, steps=400, config=c, resume=False, progress=False, log=logs.append)
    with open(tmp_path / "episodes.csv") as f:
        eps = list(csv.DictReader(f))
    assert eps[0]["outcome"] == "aborted" and eps[0]["driver"] != "actor"       # the case this test is about
    data = torch.load(tmp_path / "checkpoint.pt", weights_only=True)["replay"]["data"].double()
    assert data.shape[1] == 2 * 12 + 3 + 2 + 1 + 2 + 1
    # [o (12) | a (3) | r | not_terminal | o' (12) | aux | G | G_aux | flag]
    r_col, aux, G, G_aux, flag = data[:, 15], data[:, 29], data[:, 30], data[:, 31], data[:, 32]
    gamma = validate(c)["paper"]["ddpg"]["gamma"]
    start, checked = 0, 0
    for e in eps:
        n = int(e["steps"])
        rows = slice(start, start + n)
        if e["driver"] == "actor":
            assert (flag[rows] == 0).all() and torch.isinf(G[rows]).all()
        elif e["outcome"] == "aborted":
            assert (flag[rows] == 1).all() and torch.isinf(G[rows]).all() and (G[rows] < 0).all()
        else:
            assert (flag[rows] == 1).all() and (aux[rows] != 0).any()       # the ramped part is there to split
            for col, got in ((r_col, G), (aux, G_aux)):
                rr = col[rows].numpy()
                want = [sum(gamma ** (j - t) * rr[j] for j in range(t, n)) for t in range(n)]
                np.testing.assert_allclose(got[rows].numpy(), want, rtol=1e-5, atol=1e-3)
            checked += 1
        start += n
    assert checked > 0 and 0 < start < 400
    assert torch.isinf(G[start:400]).all()          # the episode still running at the end: no return yet
    assert any("the others failed the return filter" in line for line in logs)
    meta = load_policy(tmp_path / "final").meta
    tw = meta["trained_with"]
    assert tw["demo_bc_filter"] == "return"
    assert "where the demonstration's own return beat the critic's value of the actor" in _recipe_note(tw)
    assert "Q-filtered" in _recipe_note({k: v for k, v in tw.items() if k != "demo_bc_filter"})
    c0 = copy.deepcopy(c)
    c0["training"]["demo_bc_return_filter"] = 0
    assert meta["config_hash"] == config_hash(validate(c0))      # never in the hash
