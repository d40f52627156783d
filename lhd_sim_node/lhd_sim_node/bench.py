"""`lhd bench sim`: speed of the simulated loading task.

env_steps_per_s: control steps (0.1 s) of LhdLoading-v0 in one process with random actions,
resets (new pile, attack drive) included.

physics_only_steps_per_s: the same MJCF and the same MuJoCo substeps with no FEE and no task
code: the env run is repeated once untimed while recording, at every FEE update, what the
FEE and the hydraulics' anti-windup wrote into MuJoCo (the tendon's friction limit, the
bucket's xfrc_applied and mass, the commands, the servo set-points, the machine's placement
at each reset); the timed replay only writes those values back and calls mj_step. MuJoCo is
deterministic, so the replay goes through exactly the same states, contacts and solver
iterations as the env run, and the difference between the two times is the cost of the FEE,
the pile and the task code.

ratio = env_steps_per_s / physics_only_steps_per_s: the share of the env's time spent in
MuJoCo. Every figure is the best of `rounds` alternating runs (other load on the machine
only ever slows a run down).
"""
from __future__ import annotations

import time

import mujoco
import numpy as np

from . import fused as fused_mod

from .bucket_body import bucket_body_update
from .env import LhdLoadingEnv


def _episode_loop(env: LhdLoadingEnv, actions: np.ndarray, seed: int) -> int:
    env.reset(seed=seed)
    resets = 0
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
            resets += 1
    return resets


def _record(env: LhdLoadingEnv, actions: np.ndarray, seed: int) -> list:
    """Run the same episodes untimed and record every physics chunk's inputs."""
    sim = env.sim
    m, d = sim.model, sim.data
    chunks = []
    orig_place = sim.place_machine

    def rec_place(*args):
        orig_place(*args)
        chunks.append(("place", d.qpos.copy(), d.qvel.copy(), d.act.copy()))

    def rec_physics(n):
        if sim.fee_enabled:
            sim._update_fee()
        bucket_body_update(*sim._body_args)
        chunks.append(("step", n, d.ctrl.copy(), d.act.copy(), m.tendon_frictionloss.copy(),
                       d.xfrc_applied[sim.bid_bucket].copy(), float(m.body_mass[sim.bid_bucket]),
                       float(m.dof_frictionloss[sim.body.dof])))
        mujoco.mj_step(m, d, nstep=n)

    sim._physics, sim.place_machine = rec_physics, rec_place
    fused, sim.fused = sim.fused, False     # the Python-driven loop calls _physics at every chunk
    try:
        _episode_loop(env, actions, seed)
    finally:
        del sim._physics, sim.place_machine
        sim.fused = fused
    return chunks


def _replay(env: LhdLoadingEnv, chunks: list) -> float:
    sim = env.sim
    m, d = sim.model, sim.data
    tfl, bmass, xfrc = m.tendon_frictionloss, m.body_mass, d.xfrc_applied
    bid, dfl, dof = sim.bid_bucket, m.dof_frictionloss, sim.body.dof
    t0 = time.perf_counter()
    for ch in chunks:
        if ch[0] == "place":
            mujoco.mj_resetData(m, d)
            d.qpos[:] = ch[1]
            mujoco.mj_forward(m, d)
            continue
        _, n, ctrl, act, fl, xf, mass, curl = ch
        d.ctrl[:] = ctrl
        d.act[:] = act
        tfl[:] = fl
        dfl[dof] = curl
        xfrc[bid] = xf
        bmass[bid] = mass
        mujoco.mj_step(m, d, nstep=n)
    return time.perf_counter() - t0, d.qpos.copy()


def bench_sim(steps: int = 3000, seed: int = 0, config=None, rounds: int = 3) -> dict:
    actions = np.random.default_rng(seed).uniform(-1.0, 1.0, size=(steps, 3))
    env_t, phys_t = [], []
    env = LhdLoadingEnv(variant="rld", config=config)
    _episode_loop(env, actions[:50], seed)  # warm-up: numba and MuJoCo caches
    chunks = _record(LhdLoadingEnv(variant="rld", config=config), actions, seed)
    resets = 0
    for _ in range(rounds):
        env = LhdLoadingEnv(variant="rld", config=config)
        t0 = time.perf_counter()
        resets = _episode_loop(env, actions, seed)
        env_t.append(time.perf_counter() - t0)
        t, qpos_replay = _replay(LhdLoadingEnv(variant="rld", config=config), chunks)
        phys_t.append(t)
    # the replay must have gone through the env's states (else it timed different physics)
    replay_error = float(np.max(np.abs(qpos_replay - env.sim.data.qpos)))
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
        "replay_max_qpos_error": replay_error,
        # the compiled chunk loop (lhd_sim_node/fused.py) or, with the reason, the Python-driven one
        "compiled_loop": bool(sim.fused),
        **({} if sim.fused else {"compiled_loop_off_because": fused_mod.UNAVAILABLE_REASON or "switched off"}),
    }
