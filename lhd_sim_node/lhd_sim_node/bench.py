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


def bench_sim(steps: int = 3000, seed: int = 0, config=None) -> dict:
    env = LhdLoadingEnv(variant="rld", config=config)
    sim = env.sim
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-1.0, 1.0, size=(steps, 3))
    log = []  # ('reset', d_attack, attack_speed, attack_chunks) | ('step', u)
    orig_reset = sim.reset

    def counting_reset(*a, **k):
        t0 = sim.data.time
        orig_reset(*a, **k)
        log.append(("reset", sim.d_attack, sim.attack_speed, int(round((sim.data.time - t0) / sim.fee_dt))))

    sim.reset = counting_reset
    orig_step = sim.step

    def logging_step(u):
        log.append(("step", np.array(u)))
        orig_step(u)

    sim.step = logging_step
    env.reset(seed=seed)
    t0 = time.perf_counter()
    resets = 0
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
            resets += 1
    env_time = time.perf_counter() - t0
    # replay the physics alone
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
    phys_time = time.perf_counter() - t0
    env_sps = steps / env_time
    phys_sps = steps / phys_time
    return {
        "env_steps_per_s": round(env_sps, 1),
        "physics_only_steps_per_s": round(phys_sps, 1),
        "ratio": round(env_sps / phys_sps, 3),
        "steps": steps,
        "resets": resets,
        "substeps_per_control_step": sim.n_phys,
        "fee_updates_per_control_step": sim.n_phys // sim.fee_every,
        "timestep_s": float(m.opt.timestep),
    }
