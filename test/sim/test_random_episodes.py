"""1,000 random-action episodes: no NaN, no exception, no voxel count going negative."""
import os

import numpy as np

from lhd_sim_node.env import LhdLoadingEnv


# 300 episodes (about 30,000 steps) in `make test`; LHD_RANDOM_EPISODES=1000 for the long run
EPISODES = int(os.environ.get("LHD_RANDOM_EPISODES", "300"))


def test_random_episodes_keep_every_invariant():
    """Uniformly random actions from random piles: every observation finite and inside the
    observation space, every reward finite, the pile never gains voxels or mass, fills stay >= 0,
    the MuJoCo state finite, the loaded mass >= 0; and random actions do not load a bucket (at
    most 20 % successes, issue 13's bound for naive controllers)."""
    env = LhdLoadingEnv(variant="rlc")
    rng = np.random.default_rng(0)
    outcomes = {"success": 0, "failure": 0, "truncated": 0}     # "success": the episode's end (end zone)
    successes = 0                                                # the paper's success (EpisodeResult.success)
    for ep in range(EPISODES):
        obs, _ = env.reset(seed=int(rng.integers(1 << 30)))
        count = env.sim.pile.voxel_count()
        mass = env.sim.pile.total_mass()
        while True:
            obs, rew, term, trunc, info = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
            assert np.all(np.isfinite(obs)) and np.isfinite(rew)
            assert env.observation_space.contains(obs)
            if term or trunc:
                break
        new_count, new_mass = env.sim.pile.voxel_count(), env.sim.pile.total_mass()
        assert 0 <= new_count <= count and 0.0 <= new_mass <= mass + 1e-9
        assert env.sim.pile.fills().min() >= 0.0
        assert np.all(np.isfinite(env.sim.data.qpos)) and np.all(np.isfinite(env.sim.data.qvel))
        assert info["loaded_mass"] >= 0.0
        outcomes["truncated" if trunc else info["outcome"]] += 1
        successes += bool(info["episode_result"].success)
    assert sum(outcomes.values()) == EPISODES
    assert successes <= 0.2 * EPISODES, (successes, outcomes)
