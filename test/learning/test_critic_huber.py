"""The critics' Huber loss (training.critic_huber = d > 0): the update against one written with
torch's own huber_loss, autograd and torch.optim.Adam, with TD errors both inside and far outside
d; off (0 or the key absent) it is the squared loss it was; never in the config hash."""
PARALLEL_SAFE = True

import copy

import torch
import torch.nn.functional as F

from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig
from lhd_loading_ros.task.config import config_hash, validate


def small(cfg, d, twin=0):
    c = copy.deepcopy(cfg)
    c["training"].update({"hidden_sizes": [32, 32], "critic_huber": d, "twin_critics": twin})
    return c


def reference_update(actor, critic, actor_t, critic_t, oa, r, nd, o2, cfg):
    """DDPG with the critic regressing by 2 * torch's huber_loss(delta = d) (the squared loss inside
    d), the actor ascending Q, the targets following softly."""
    with torch.no_grad():
        y = cfg.reward_scale * r + cfg.gamma * nd * critic_t(torch.cat([o2, actor_t(o2)], 1))
    q = critic(oa)
    loss = 2.0 * F.huber_loss(q, y, delta=cfg.critic_huber) if cfg.critic_huber > 0 else ((q - y) ** 2).mean()
    critic.opt.zero_grad()
    loss.backward()
    critic.opt.step()
    o = oa[:, :12]
    actor.opt.zero_grad()
    (-critic(torch.cat([o, actor(o)], 1)).mean()).backward()
    actor.opt.step()
    with torch.no_grad():
        for net, tgt in ((actor, actor_t), (critic, critic_t)):
            for p, tp in zip(net.parameters(), tgt.parameters()):
                tp.mul_(1 - cfg.tau).add_(cfg.tau * p)


def run_both(cfg, d):
    dc = DdpgConfig.from_config(small(cfg, d))
    agent = DdpgAgent(dc, seed=5)
    nets = [agent.actor, agent.critic, agent.actor_t, agent.critic_t]
    seqs = [n.to_sequential() for n in nets]
    seqs[0].opt = torch.optim.Adam(seqs[0].parameters(), lr=dc.actor_lr)
    seqs[1].opt = torch.optim.Adam(seqs[1].parameters(), lr=dc.critic_lr)
    g = torch.Generator().manual_seed(6)
    clipped = 0
    for _ in range(4):
        oa, o2 = torch.rand(dc.batch_size, 15, generator=g) * 2 - 1, torch.rand(dc.batch_size, 12, generator=g)
        r = torch.randn(dc.batch_size, 1, generator=g) * 300      # scaled: TD errors of a few units
        nd = (torch.rand(dc.batch_size, 1, generator=g) > 0.2).float()
        err, _ = agent.update(oa, r, nd, o2)
        clipped += int((err.abs() > d).sum()) if d > 0 else 0
        reference_update(*seqs, oa, r, nd, o2, dc)
    return nets, seqs, clipped, dc.batch_size


def test_the_huber_update_matches_an_autograd_reference(cfg):
    nets, seqs, clipped, b = run_both(cfg, 1.0)
    assert 0.2 * 4 * b < clipped < 0.9 * 4 * b          # both regimes of the loss are exercised
    for mine, ref in zip(nets, seqs):
        torch.testing.assert_close(mine.flat, torch.cat([p.detach().reshape(-1) for p in ref.parameters()]),
                                   rtol=1e-4, atol=1e-5)


def test_off_it_is_the_squared_loss(cfg):
    nets, seqs, _, _ = run_both(cfg, 0.0)
    for mine, ref in zip(nets, seqs):
        torch.testing.assert_close(mine.flat, torch.cat([p.detach().reshape(-1) for p in ref.parameters()]),
                                   rtol=1e-4, atol=1e-5)
    # a huge delta clips nothing: the same weights as the squared loss
    a, b = DdpgAgent(DdpgConfig.from_config(small(cfg, 0.0)), seed=1), \
        DdpgAgent(DdpgConfig.from_config(small(cfg, 1e6)), seed=1)
    g = torch.Generator().manual_seed(2)
    oa, o2 = torch.rand(256, 15, generator=g), torch.rand(256, 12, generator=g)
    r, nd = torch.randn(256, 1, generator=g) * 300, torch.ones(256, 1)
    a.update(oa, r, nd, o2)
    b.update(oa, r, nd, o2)
    assert torch.equal(a.critic.flat, b.critic.flat)


def test_not_in_the_hash_and_absent_means_off(cfg):
    assert config_hash(validate(small(cfg, 0.0))) == config_hash(validate(small(cfg, 2.0)))
    c = copy.deepcopy(cfg)
    del c["training"]["critic_huber"]
    assert validate(c)["training"]["critic_huber"] == 0.0
    assert DdpgConfig.from_config(c).critic_huber == 0.0
