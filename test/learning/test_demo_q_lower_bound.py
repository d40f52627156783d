"""The demonstrations' own returns as a lower bound on the critics' target (training.demo_q_lower_bound = 1): the update
against one written with autograd and torch.optim.Adam whose target is max(y, reward_scale G) where G is known; a row
without a return (G = -inf) keeps y; off it is the update it was; refused without the return filter; in a real run a
demonstration cut by the time limit stores no return with it on, and does without it; never in the hash."""
PARALLEL_SAFE = True

import copy
import csv
import dataclasses

import pytest
import torch

from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig
from lhd_loading_ros.task.config import ConfigError, config_hash, validate


def small_cfg(cfg, **training):
    c = copy.deepcopy(cfg)
    c["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 400, "checkpoint_every": 400,
                          "hidden_sizes": [32, 32], **training})
    return c


def reference_update(actor, critic, actor_t, critic_t, oa, r, nd, o2, demo, G, cfg, bound: bool):
    """DDPG with the return-filtered cloning (as test_demo_bc.py), the critic's target raised to reward_scale G
    where G is finite and larger when `bound`. Returns how many rows the bound raised."""
    with torch.no_grad():
        y = cfg.reward_scale * r + cfg.gamma * nd * critic_t(torch.cat([o2, actor_t(o2)], 1))
        raised = torch.isfinite(G) & (cfg.reward_scale * G > y)
        if bound:
            y = torch.where(raised, cfg.reward_scale * G, y)
    critic.opt.zero_grad()
    ((critic(oa) - y) ** 2).mean().backward()
    critic.opt.step()
    o, a = oa[:, :12], oa[:, 12:]
    pi = actor(o)
    with torch.no_grad():
        f = demo * (cfg.reward_scale * G > critic(torch.cat([o, pi], 1))).float()
    loss = -critic(torch.cat([o, pi], 1)).mean() + cfg.demo_bc * (f * ((pi - a) ** 2).sum(1, keepdim=True)).sum() / oa.shape[0]
    actor.opt.zero_grad()
    loss.backward()
    actor.opt.step()
    with torch.no_grad():
        for net, tgt in ((actor, actor_t), (critic, critic_t)):
            for p, tp in zip(net.parameters(), tgt.parameters()):
                tp.mul_(1 - cfg.tau).add_(cfg.tau * p)
    return int(raised.sum())


@pytest.mark.parametrize("bound", [1, 0])
def test_the_update_matches_an_autograd_reference(cfg, bound):
    dc = dataclasses.replace(DdpgConfig.from_config(small_cfg(cfg)), demo_bc=1.0, batch_size=128,
                             demo_bc_return_filter=1, demo_q_lower_bound=bound)
    agent = DdpgAgent(dc, seed=5)
    nets = [n.to_sequential() for n in (agent.actor, agent.critic, agent.actor_t, agent.critic_t)]
    nets[0].opt = torch.optim.Adam(nets[0].parameters(), lr=dc.actor_lr)
    nets[1].opt = torch.optim.Adam(nets[1].parameters(), lr=dc.critic_lr)
    g = torch.Generator().manual_seed(6)
    raised = 0
    for _ in range(5):
        oa, o2 = torch.rand(dc.batch_size, 15, generator=g) * 2 - 1, torch.rand(dc.batch_size, 12, generator=g)
        r = torch.randn(dc.batch_size, 1, generator=g) * 500
        nd = (torch.rand(dc.batch_size, 1, generator=g) > 0.2).float()
        demo = (torch.rand(dc.batch_size, 1, generator=g) < 0.4).float()
        G = torch.where(demo > 0, torch.randn(dc.batch_size, 1, generator=g) * 8.0, torch.tensor(-float("inf")))
        G[::5] = -float("inf")                       # demonstrations whose return is not known (yet, or cut)
        agent.update(oa, r, nd, o2, demo, G)
        raised += reference_update(*nets, oa, r, nd, o2, demo, G, dc, bool(bound))
        for mine, ref in zip((agent.actor, agent.critic), nets[:2]):
            torch.testing.assert_close(mine.flat, torch.cat([q.detach().reshape(-1) for q in ref.parameters()]),
                                       rtol=1e-4, atol=1e-5)
    assert raised > 20          # the bound bit on many rows (and, with it off, the reference ignored them too)


def test_refused_without_the_return_filter_and_never_in_the_hash(cfg):
    with pytest.raises(ConfigError, match="demo_q_lower_bound = 1 only with training.demo_bc > 0 and"):
        validate(small_cfg(cfg, demo_q_lower_bound=1, demo_bc=1.0, demo_bc_return_filter=0))
    with pytest.raises(ConfigError, match="demo_q_lower_bound = 1 only with"):
        validate(small_cfg(cfg, demo_q_lower_bound=1, demo_bc=0.0))
    on = validate(small_cfg(cfg, demo_q_lower_bound=1, demo_bc=1.0, demo_bc_return_filter=1))
    off = validate(small_cfg(cfg, demo_q_lower_bound=0, demo_bc=1.0, demo_bc_return_filter=1))
    assert config_hash(on) == config_hash(off)
    c = copy.deepcopy(cfg)
    del c["training"]["demo_q_lower_bound"]
    assert validate(c)["training"]["demo_q_lower_bound"] == 0
    assert DdpgConfig.from_config(c).demo_q_lower_bound == 0


@pytest.mark.parametrize("bound", [1, 0])
def test_a_demonstration_cut_by_the_time_limit_bounds_nothing(cfg, tmp_path, bound):
    """A real run whose episodes are cut at 12 steps: every demonstration times out. With the bound on none of its
    rows carries a return (a realised return cut short is no lower bound); off, as before, each carries one."""
    from lhd_loading_ros.learning.ship import _recipe_note
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.policy.actor_file import load_policy

    c = small_cfg(cfg, demo_share=0.5, demo_bc=1.0, demo_bc_return_filter=1, demo_q_lower_bound=bound,
                  episode_seed_offset=0)
    c["paper"]["episode"]["max_steps"] = 12
    train("rld", 3, tmp_path, steps=300, config=c, resume=False, progress=False, log=lambda s: None)
    with open(tmp_path / "episodes.csv") as f:
        eps = list(csv.DictReader(f))
    data = torch.load(tmp_path / "checkpoint.pt", weights_only=True)["replay"]["data"].double()
    G, flag = data[:, -2], data[:, -1]           # [o | a | r | not_terminal | o' | G | flag]
    start, demos = 0, 0
    for e in eps:
        n = int(e["steps"])
        rows = slice(start, start + n)
        if e["driver"] != "actor":
            assert e["outcome"] == "timeout" and (flag[rows] == 1).all()
            assert torch.isinf(G[rows]).all() if bound else torch.isfinite(G[rows]).all()
            demos += 1
        start += n
    assert demos >= 3
    tw = load_policy(tmp_path / "final").meta["trained_with"]
    assert ("demo_q_lower_bound" in tw) == bool(bound)
    assert ("lower bound on the critics' target" in _recipe_note(tw)) == bool(bound)
