"""1,000 random-action episodes: no NaN, no exception, no voxel count going negative."""
import numpy as np

from lhd_sim_node.env import LhdLoadingEnv


def test_thousand_random_episodes():
    env = LhdLoadingEnv(variant="rlc")
    rng = np.random.default_rng(0)
    outcomes = {"success": 0, "failure": 0, "truncated": 0}
    for ep in range(1000):
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
    assert sum(outcomes.values()) == 1000
