"""The penalty on the actor's tanh input (training.actor_preact_l2 = w > 0): the update against one written with
autograd and torch.optim.Adam (actor loss -mean Q(o, tanh z) + w mean ||z||^2); a saturated output that the critic
cannot move (tanh'(20) is 0 in float32) comes off its bound only with the penalty; off (0 or the key absent) the
update is the one it was; never in the config hash; the actor's card names it."""
PARALLEL_SAFE = True

import copy

import torch

from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig
from lhd_loading_ros.task.config import config_hash, validate


def small(cfg, w, **training):
    c = copy.deepcopy(cfg)
    c["training"].update({"hidden_sizes": [32, 32], "actor_preact_l2": w, "twin_critics": 0, "demo_bc": 0.0,
                          **training})
    return c


def reference_update(actor, critic, actor_t, critic_t, oa, r, nd, o2, cfg, w):
    """DDPG whose actor descends -mean Q(o, tanh z(o)) + w mean_i sum_j z_ij^2 by autograd."""
    with torch.no_grad():
        y = cfg.reward_scale * r + cfg.gamma * nd * critic_t(torch.cat([o2, actor_t(o2)], 1))
    loss = ((critic(oa) - y) ** 2).mean()
    critic.opt.zero_grad()
    loss.backward()
    critic.opt.step()
    o = oa[:, :12]
    z = actor[:-1](o)                     # the Sequential's last module is the Tanh
    actor.opt.zero_grad()
    (-critic(torch.cat([o, torch.tanh(z)], 1)).mean() + w * (z * z).sum(1).mean()).backward()
    actor.opt.step()
    with torch.no_grad():
        for net, tgt in ((actor, actor_t), (critic, critic_t)):
            for p, tp in zip(net.parameters(), tgt.parameters()):
                tp.mul_(1 - cfg.tau).add_(cfg.tau * p)


def run_both(cfg, w, bias=0.0):
    dc = DdpgConfig.from_config(small(cfg, w))
    agent = DdpgAgent(dc, seed=5)
    with torch.no_grad():
        agent.actor.b[-1].add_(bias)      # outputs pushed towards saturation: the penalty's gradient is large
        agent.actor_t.copy_from(agent.actor)
    nets = [agent.actor, agent.critic, agent.actor_t, agent.critic_t]
    seqs = [n.to_sequential() for n in nets]
    seqs[0].opt = torch.optim.Adam(seqs[0].parameters(), lr=dc.actor_lr)
    seqs[1].opt = torch.optim.Adam(seqs[1].parameters(), lr=dc.critic_lr)
    g = torch.Generator().manual_seed(6)
    for _ in range(4):
        oa, o2 = torch.rand(dc.batch_size, 15, generator=g) * 2 - 1, torch.rand(dc.batch_size, 12, generator=g)
        r = torch.randn(dc.batch_size, 1, generator=g) * 300
        nd = (torch.rand(dc.batch_size, 1, generator=g) > 0.2).float()
        agent.update(oa, r, nd, o2)
        reference_update(*seqs, oa, r, nd, o2, dc, w)
    return agent, nets, seqs


def test_the_penalised_update_matches_an_autograd_reference(cfg):
    for bias in (0.0, 3.0):
        agent, nets, seqs = run_both(cfg, 0.05, bias)
        for mine, ref in zip(nets, seqs):
            torch.testing.assert_close(mine.flat, torch.cat([p.detach().reshape(-1) for p in ref.parameters()]),
                                       rtol=1e-4, atol=1e-5)
        # the logged statistic is the last batch's mean ||z||^2, z from the actor before its step
        assert agent.preact_sq > (bias ** 2 if bias else 0.0)


def test_off_it_is_the_update_it_was(cfg):
    agent, nets, seqs = run_both(cfg, 0.0)
    for mine, ref in zip(nets, seqs):
        torch.testing.assert_close(mine.flat, torch.cat([p.detach().reshape(-1) for p in ref.parameters()]),
                                   rtol=1e-4, atol=1e-5)
    assert agent.preact_sq != agent.preact_sq          # not computed: nan


def fixed_critic_prefers_low_bucket(agent):
    """Q(o, a) = 1 - a_bucket (a in [-1, 1]): one ReLU unit carries 1 - a_bucket > 0 through both layers."""
    with torch.no_grad():
        for W, b in zip(agent.critic.W, agent.critic.b):
            W.zero_()
            b.zero_()
        agent.critic.W[0][0, 12 + 2] = -1.0
        agent.critic.b[0][0] = 1.0
        agent.critic.W[1][0, 0] = 1.0
        agent.critic.W[2][0, 0] = 1.0
        agent.critic_t.copy_from(agent.critic)


def bucket_after(cfg, w, updates=300):
    """An actor whose bucket output sits at tanh(20) (1.0 in float32) under a critic that wants it lower, the critic
    held still: the bucket action and its tanh input after `updates` updates."""
    c = small(cfg, w)
    c["paper"]["ddpg"].update({"actor_lr": 0.01, "batch_size": 64})
    agent = DdpgAgent(DdpgConfig.from_config(c), seed=3)
    agent.critic_opt.lr = 0.0                          # the critic held still (the config refuses a rate of 0)
    fixed_critic_prefers_low_bucket(agent)
    with torch.no_grad():
        agent.actor.b[-1][2] = 20.0
    g = torch.Generator().manual_seed(4)
    o = torch.rand(64, 12, generator=g) * 2 - 1
    before = agent.actor(o)[:, 2]
    assert bool((before == 1.0).all())                 # saturated: tanh'(z) = 1 - 1^2 = 0 exactly
    for _ in range(updates):
        oa = torch.cat([o, torch.rand(64, 3, generator=g) * 2 - 1], 1)
        agent.update(oa, torch.zeros(64, 1), torch.ones(64, 1), o)
    return agent.actor(o)[:, 2], agent.actor.out_preactivation(agent.actor.forward(o)[1])[:, 2]


def test_a_saturated_output_moves_only_with_the_penalty(cfg):
    a_off, z_off = bucket_after(cfg, 0.0)
    assert bool((a_off == 1.0).all()) and float(z_off.min()) > 19.0     # the critic's gradient never arrives
    a_on, z_on = bucket_after(cfg, 1e-3)
    # the penalty brings z back to where tanh passes the critic's gradient, which then drives the bucket down
    assert float(a_on.max()) < -0.9, a_on


def test_not_in_the_hash_absent_means_off_and_on_the_card(cfg):
    assert config_hash(validate(small(cfg, 0.0))) == config_hash(validate(small(cfg, 1e-3)))
    c = copy.deepcopy(cfg)
    del c["training"]["actor_preact_l2"]
    assert validate(c)["training"]["actor_preact_l2"] == 0.0
    assert DdpgConfig.from_config(c).actor_preact_l2 == 0.0
    bad = small(cfg, -1e-3)
    try:
        validate(bad)
    except ValueError as e:
        assert "actor_preact_l2" in str(e)
    else:
        raise AssertionError("a negative actor_preact_l2 was accepted")


def test_the_card_and_the_recipe_note_name_it(cfg, tmp_path):
    from lhd_loading_ros.learning.export import export_actor
    from lhd_loading_ros.learning.mlp import FlatMlp
    from lhd_loading_ros.learning.ship import _recipe_note
    from lhd_loading_ros.policy.actor_file import load_policy

    for w, d in ((1e-3, "on"), (0.0, "off")):
        export_actor(tmp_path / d, FlatMlp([12, 8, 3], out_act="tanh"), validate(small(cfg, w)),
                     {"variant": "rlc", "seed": 0, "steps": 0})
        tw = load_policy(tmp_path / d).meta["trained_with"]
        if w:
            assert tw["actor_preact_l2"] == 1e-3
            assert "a penalty on the actor's tanh input (weight 0.001)" in _recipe_note(tw)
        else:
            assert "actor_preact_l2" not in tw and "tanh input" not in _recipe_note(tw)
