"""`lhd bench sim`: speed of the simulated loading task.

env_steps_per_s: control steps (0.1 s) of LhdLoading-v0 in one process with random
actions, resets (new pile, attack drive) included.
physics_only_steps_per_s: the same MJCF and the same physics workload (the same number of
MuJoCo substeps per control step, the same attack drives at the resets) replayed with the
FEE and all task code switched off. ratio = env / physics_only: the share of the time the
simulator spends in MuJoCo itself.
"""
from __future__ import annotations

import time

import mujoco
import numpy as np

from .env import LhdLoadingEnv


def _run_env(steps: int, seed: int, config) -> tuple[float, list, int]:
    env = LhdLoadingEnv(variant="rld", config=config)
    sim = env.sim
    actions = np.random.default_rng(seed).uniform(-1.0, 1.0, size=(steps, 3))
    log = []  # ('reset', d_attack, attack_speed, attack_chunks) | ('step', u)
    orig_reset, orig_step = sim.reset, sim.step

    def counting_reset(*a, **k):
        t0 = sim.data.time
        orig_reset(*a, **k)
        log.append(("reset", sim.d_attack, sim.attack_speed, int(round((sim.data.time - t0) / sim.fee_dt))))

    def logging_step(u):
        log.append(("step", u))
        orig_step(u)

    sim.reset, sim.step = counting_reset, logging_step
    env.reset(seed=seed)
    resets = 0
    t0 = time.perf_counter()
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
            resets += 1
    return time.perf_counter() - t0, log, resets, env


def _replay_physics(env, log) -> float:
    """The same physics workload without FEE and task code: same MJCF, same substeps per
    control step, same commands, same attack drives at the resets."""
    sim = env.sim
    m, d = sim.model, sim.data
    sim.fee_enabled = False
    t0 = time.perf_counter()
    first = True
    for ev in log:
        if ev[0] == "reset":
            if not first:
                sim.place_machine(ev[1])
                sim.set_command(np.array([ev[2], 0.0, 0.0]))
                for _ in range(ev[3]):
                    mujoco.mj_step(m, d, nstep=sim.fee_every)
            first = False
        else:
            sim.set_command(ev[1])
            mujoco.mj_step(m, d, nstep=sim.n_phys)
    return time.perf_counter() - t0


def bench_sim(steps: int = 3000, seed: int = 0, config=None, rounds: int = 3) -> dict:
    """Best of `rounds` alternating runs of each (the machine's other load only slows runs down)."""
    env_t, phys_t = [], []
    for _ in range(rounds):
        t, log, resets, env = _run_env(steps, seed, config)
        env_t.append(t)
        phys_t.append(_replay_physics(env, log))
    sim = env.sim
    env_sps = steps / min(env_t)
    phys_sps = steps / min(phys_t)
    return {
        "env_steps_per_s": round(env_sps, 1),
        "physics_only_steps_per_s": round(phys_sps, 1),
        "ratio": round(env_sps / phys_sps, 3),
        "steps": steps,
        "rounds": rounds,
        "resets": resets,
        "substeps_per_control_step": sim.n_phys,
        "fee_updates_per_control_step": sim.n_phys // sim.fee_every,
        "timestep_s": float(sim.model.opt.timestep),
    }
