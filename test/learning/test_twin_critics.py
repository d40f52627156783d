"""Clipped double Q (training.twin_critics = 1; Fujimoto et al. 2018, without TD3's delayed actor
and target smoothing): the update against one written with autograd and torch.optim.Adam, the
single-critic agent unchanged by the option's existence, checkpoints that refuse the other
layout, the config hash that the option never enters, and a short real run that records it on
the card and resumes."""
PARALLEL_SAFE = True

import copy

import pytest
import torch

from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig
from lhd_loading_ros.task.config import config_hash, validate


def small(cfg, twin):
    c = copy.deepcopy(cfg)
    c["training"].update({"learning_starts": 256, "eval_episodes": 2, "eval_every": 150,
                          "checkpoint_every": 150, "hidden_sizes": [32, 32], "twin_critics": twin})
    return c


def reference_update(actor, c1, c2, actor_t, c1_t, c2_t, oa, r, nd, o2, cfg):
    """Clipped double Q written with autograd: y = s r + gamma nd min(Q1'(o', mu'(o')), Q2'(...)),
    both critics regress on y, the actor ascends Q1, all four targets follow softly."""
    with torch.no_grad():
        o2a2 = torch.cat([o2, actor_t(o2)], 1)
        y = cfg.reward_scale * r + cfg.gamma * nd * torch.minimum(c1_t(o2a2), c2_t(o2a2))
    for c in (c1, c2):
        loss = ((c(oa) - y) ** 2).mean()
        c.opt.zero_grad()
        loss.backward()
        c.opt.step()
    o = oa[:, :12]
    actor_loss = -c1(torch.cat([o, actor(o)], 1)).mean()
    actor.opt.zero_grad()
    actor_loss.backward()
    actor.opt.step()
    with torch.no_grad():
        for net, tgt in ((actor, actor_t), (c1, c1_t), (c2, c2_t)):
            for p, tp in zip(net.parameters(), tgt.parameters()):
                tp.mul_(1 - cfg.tau).add_(cfg.tau * p)


def test_the_update_matches_an_autograd_reference(cfg):
    dc = DdpgConfig.from_config(small(cfg, 1))
    agent = DdpgAgent(dc, seed=3)
    nets = [agent.actor, agent.critic, agent.critic2, agent.actor_t, agent.critic_t, agent.critic2_t]
    seqs = [n.to_sequential() for n in nets]
    # the two critics start apart (else the min would be either)
    assert not torch.equal(agent.critic.flat, agent.critic2.flat)
    seqs[0].opt = torch.optim.Adam(seqs[0].parameters(), lr=dc.actor_lr)
    for s in seqs[1:3]:
        s.opt = torch.optim.Adam(s.parameters(), lr=dc.critic_lr)
    g = torch.Generator().manual_seed(4)
    for _ in range(4):
        oa, o2 = torch.rand(dc.batch_size, 15, generator=g) * 2 - 1, torch.rand(dc.batch_size, 12, generator=g)
        r = torch.randn(dc.batch_size, 1, generator=g) * 500
        nd = (torch.rand(dc.batch_size, 1, generator=g) > 0.2).float()
        agent.update(oa, r, nd, o2)
        reference_update(*seqs, oa, r, nd, o2, dc)
    for mine, ref in zip(nets, seqs):
        torch.testing.assert_close(mine.flat, torch.cat([p.detach().reshape(-1) for p in ref.parameters()]),
                                   rtol=1e-4, atol=1e-5)


def test_one_critic_is_the_agent_it_was(cfg):
    """With the option off (and with the key absent) the agent draws the same initial weights as
    before the option existed: the second critic is drawn after everything else."""
    one = DdpgAgent(DdpgConfig.from_config(small(cfg, 0)), seed=9)
    c = small(cfg, 0)
    del c["training"]["twin_critics"]
    absent = DdpgAgent(DdpgConfig.from_config(c), seed=9)
    two = DdpgAgent(DdpgConfig.from_config(small(cfg, 1)), seed=9)
    for name in ("actor", "critic", "actor_t", "critic_t"):
        assert torch.equal(getattr(one, name).flat, getattr(absent, name).flat)
        assert torch.equal(getattr(one, name).flat, getattr(two, name).flat)
    assert not one.twin and not hasattr(one, "critic2")


def test_checkpoints_refuse_the_other_layout(cfg):
    one = DdpgAgent(DdpgConfig.from_config(small(cfg, 0)), seed=1)
    two = DdpgAgent(DdpgConfig.from_config(small(cfg, 1)), seed=2)
    with pytest.raises(ValueError, match="twin_critics"):
        one.load_state_dict(two.state_dict())
    with pytest.raises(ValueError, match="twin_critics"):
        two.load_state_dict(one.state_dict())
    again = DdpgAgent(DdpgConfig.from_config(small(cfg, 1)), seed=5)
    again.load_state_dict(two.state_dict())
    assert torch.equal(again.critic2.flat, two.critic2.flat) and torch.equal(again.critic2_t.flat, two.critic2_t.flat)


def test_the_option_is_not_in_the_config_hash(cfg):
    c = copy.deepcopy(cfg)
    h = config_hash(c)
    c["training"]["twin_critics"] = 1
    assert config_hash(validate(c)) == h
    del c["training"]["twin_critics"]
    assert config_hash(c) == h
    c["training"]["twin_critics"] = 2
    with pytest.raises(Exception, match="twin_critics"):
        validate(c)


def test_a_short_run_records_the_option_and_resumes(cfg, tmp_path):
    from lhd_loading_ros.learning.train import train
    from lhd_loading_ros.policy.actor_file import load_policy

    c = small(cfg, 1)
    out = tmp_path / "run"
    train("rld", 7, out, steps=300, config=c, progress=False, log=lambda *a: None)
    st = torch.load(out / "checkpoint.pt", weights_only=True)
    assert "critic2" in st["agent"] and st["agent"]["updates"] == 300 - 256 + 1
    # the second critic learned (moved from its initial weights) and differs from the first
    init = DdpgAgent(DdpgConfig.from_config(c), seed=7)
    assert not torch.equal(st["agent"]["critic2"], init.critic2.flat)
    assert not torch.equal(st["agent"]["critic2"], st["agent"]["critic"])
    meta = load_policy(out / "final").meta
    assert meta["trained_with"]["twin_critics"] == 1
    assert meta["config_hash"] == config_hash(small(cfg, 0))       # the same as one critic's
    logs = []
    train("rld", 7, out, steps=450, config=c, progress=False, log=logs.append)
    assert any("resumed" in m for m in logs)
    # a single-critic run does not resume it
    with pytest.raises(ValueError, match="twin_critics"):
        train("rld", 7, out, steps=600, config=small(cfg, 0), progress=False, log=lambda *a: None)
