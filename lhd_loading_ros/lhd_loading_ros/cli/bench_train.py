"""``lhd bench train``: the cost of the training loop, measured, and the projected time of
the paper's protocol (300,000 steps, one update each, 120 evaluation episodes every 10,000).

updates_per_s     DDPG updates alone (sample a batch of 256, critic step, actor step, targets)
env_steps_per_s   environment steps with action selection and noise, without updates
loop_steps_per_s  the real loop: action, env step, replay write, update
projected_protocol_min = total_steps / loop_steps_per_s
                         + evaluations x eval_episodes x eval_episode_steps / env_steps_per_s
With --vs-sb3, Stable-Baselines3's DDPG (same networks, hyperparameters, OU noise and
environment; an optional extra, not a dependency) is timed the same way in the same run.

With --jobs N (N > 1) the same measurement runs in N processes at once, as a study runs its
trials (`lhd sweep --jobs N`, `lhd train --seeds --jobs N`): the rates are the processes' mean,
so they include what the runs cost each other (caches, memory bandwidth), and
projected_study_min = ceil(10 / N) x projected_protocol_min is issue 14's whole study (2
variants x 5 seeds) run N at a time. --config / --randomize time the recipe a study trains.
The projection is a lower bound: it times the loop's first few thousand steps, and a measured
study (docs/training.md) shows what it leaves out.
"""
from __future__ import annotations

import math
import multiprocessing
import time

import numpy as np
import torch

from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig, OUNoise, ReplayBuffer

EVAL_EPISODE_STEPS = 40     # a trained policy's episode (about 4 s at 10 Hz); see docs/training.md


STUDY_RUNS = 10        # issue 14's study: 2 variants x 5 seeds


def bench_train_jobs(jobs: int = 1, steps: int = 3000, seed: int = 0, config=None, randomize: bool = False) -> dict:
    """bench_train in `jobs` processes at once (one per seed seed..seed+jobs-1); the mean of their
    rates, and the projected time of the whole study run `jobs` at a time."""
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if jobs == 1:
        res = bench_train(steps=steps, seed=seed, config=config, randomize=randomize)
        runs = [res]
    else:
        if isinstance(config, dict):
            raise ValueError("bench_train_jobs with jobs > 1 takes a parameter file's path (or None), not a dict")
        ctx = multiprocessing.get_context("spawn")
        with ctx.Manager() as manager, ctx.Pool(jobs) as pool:
            # the processes start timing together (their imports take different times)
            barrier = manager.Barrier(jobs)
            runs = pool.starmap(_bench_one, [(steps, seed + i, config, randomize, barrier) for i in range(jobs)])
        res = dict(runs[0])
        for k in ("updates_per_s", "env_steps_per_s", "loop_steps_per_s", "projected_protocol_min"):
            res[k] = round(sum(r[k] for r in runs) / jobs, 2)
    res["jobs"] = jobs
    res["projected_study_min"] = round(math.ceil(STUDY_RUNS / jobs) * res["projected_protocol_min"], 1)
    return res


def _bench_one(steps, seed, config, randomize, barrier):
    return bench_train(steps=steps, seed=seed, config=config, randomize=randomize, barrier=barrier)


def bench_train(steps: int = 3000, seed: int = 0, config=None, variant: str = "rld", vs_sb3: bool = False,
                randomize: bool = False, barrier=None) -> dict:
    from lhd_sim_node.env import LhdLoadingEnv

    cfg = config if isinstance(config, dict) else load_config(config)
    if randomize:
        cfg = {**cfg, "randomization": {**cfg["randomization"], "enabled": 1}}
    dc = DdpgConfig.from_config(cfg)
    torch.set_num_threads(cfg["training"]["torch_threads"])
    env = LhdLoadingEnv(variant, cfg)
    agent = DdpgAgent(dc, seed)
    # the replay as train() builds it: the tilt term apart under its ramp, the demonstration flag
    # for behaviour cloning (a share training.demo_share of the rows flagged, so that the update
    # timed is the recipe's, its Q-filter and cloning term included)
    ramp = float(cfg["task"].get("r_tilt_per_deg", 0.0)) > 0 and float(cfg["task"].get("r_tilt_ramp_after_success", 0.0)) > 0
    replay = ReplayBuffer(dc.replay_size, aux=ramp, demo=dc.demo_bc > 0.0,
                          demo_return=dc.demo_bc > 0.0 and bool(dc.demo_bc_return_filter))
    demo_share = float(cfg["training"].get("demo_share", 0.0))
    flag_rng = np.random.default_rng([seed, 0xDE])
    noise = OUNoise(3, dc.ou_mu, dc.ou_sigma, dc.ou_theta, dc.ou_dt, np.random.default_rng(seed))
    obs, _ = env.reset(seed=seed)
    ep = 0

    def env_step():
        nonlocal obs, ep
        a = np.clip(agent.act(obs) + noise.sample(), -1.0, 1.0)
        obs2, r, term, trunc, _ = env.step(a)
        flag = replay.demo and flag_rng.random() < demo_share
        ticket = replay.add(obs, a, r, term, obs2, demo=flag)
        if flag and replay.demo_return:     # (a return for the flagged row, so that the filter sees numbers)
            replay.set_demo_return([(ticket, r, 0.0)], dc.gamma)
        obs = obs2
        if term or trunc:
            ep += 1
            noise.reset()
            obs, _ = env.reset(seed=seed + ep)

    n_warm = max(dc.learning_starts, dc.batch_size)
    if barrier is not None:
        barrier.wait()
    t = time.perf_counter()
    for _ in range(n_warm):
        env_step()
    env_rate = n_warm / (time.perf_counter() - t)
    for _ in range(20):
        agent.update(*replay.sample(dc.batch_size, agent.gen))
    t = time.perf_counter()
    for _ in range(steps):
        agent.update(*replay.sample(dc.batch_size, agent.gen))
    upd_rate = steps / (time.perf_counter() - t)
    t = time.perf_counter()
    for _ in range(steps):
        env_step()
        agent.update(*replay.sample(dc.batch_size, agent.gen))
    loop_rate = steps / (time.perf_counter() - t)
    n_evals = dc.total_steps // dc.eval_every
    eval_s = n_evals * dc.eval_episodes * EVAL_EPISODE_STEPS / env_rate
    res = {
        "updates_per_s": round(upd_rate, 1), "env_steps_per_s": round(env_rate, 1),
        "loop_steps_per_s": round(loop_rate, 1),
        "projected_protocol_min": round((dc.total_steps / loop_rate + eval_s) / 60.0, 2),
        "hidden_sizes": list(dc.hidden_sizes), "batch_size": dc.batch_size, "torch_threads": torch.get_num_threads(),
        "steps": steps, "randomize": bool(int(cfg["randomization"].get("enabled", 0))),
    }
    if vs_sb3:
        res.update(_bench_sb3(cfg, dc, variant, steps, seed))
        res["speedup_vs_sb3"] = round(res["updates_per_s"] / res["sb3_updates_per_s"], 2)
    return res


def _bench_sb3(cfg, dc: DdpgConfig, variant: str, steps: int, seed: int) -> dict:
    try:
        from stable_baselines3 import DDPG
        from stable_baselines3.common.noise import OrnsteinUhlenbeckActionNoise
    except ImportError as exc:
        raise SystemExit("lhd bench train --vs-sb3 needs Stable-Baselines3, an optional benchmark extra: "
                         f".venv/bin/pip install stable-baselines3 ({exc})") from None
    from lhd_sim_node.env import LhdLoadingEnv

    class PaperDDPG(DDPG):
        """SB3 has one learning rate for actor and critic; keep the paper's two."""

        def _update_learning_rate(self, optimizers):
            for g in self.actor.optimizer.param_groups:
                g["lr"] = dc.actor_lr
            for g in self.critic.optimizer.param_groups:
                g["lr"] = dc.critic_lr

    env = LhdLoadingEnv(variant, cfg)
    noise = OrnsteinUhlenbeckActionNoise(mean=np.full(3, dc.ou_mu), sigma=np.full(3, dc.ou_sigma),
                                         theta=dc.ou_theta, dt=dc.ou_dt)
    model = PaperDDPG("MlpPolicy", env, learning_rate=dc.critic_lr, buffer_size=dc.replay_size,
                      learning_starts=dc.learning_starts, batch_size=dc.batch_size, tau=dc.tau, gamma=dc.gamma,
                      train_freq=1, gradient_steps=1, action_noise=noise, seed=seed, device="cpu",
                      policy_kwargs={"net_arch": list(dc.hidden_sizes)}, verbose=0)
    model.learn(total_timesteps=max(dc.learning_starts, dc.batch_size) + 50)
    t = time.perf_counter()
    model.train(gradient_steps=steps, batch_size=dc.batch_size)
    upd = steps / (time.perf_counter() - t)
    t = time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    loop = steps / (time.perf_counter() - t)
    return {"sb3_updates_per_s": round(upd, 1), "sb3_loop_steps_per_s": round(loop, 1)}
