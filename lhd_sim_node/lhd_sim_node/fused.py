"""One compiled loop over the FEE chunks of a control period: pile, bucket body and MuJoCo.

A control period (0.1 s) is ``n_phys / fee_every`` chunks (5 at the shipped config); each chunk
updates the FEE (``fee_kernel.fee_update``), the whole-bucket limits
(``bucket_body.bucket_body_update``) and then runs ``fee_every`` MuJoCo steps. Driven from
Python, every chunk pays two numba dispatches (each type-checks its 17-24 arguments) and one
``mujoco.mj_step`` call; at about 12 us of MuJoCo per step these overheads were a tenth of the
simulator's time. Here the same calls, in the same order on the same arrays, run inside one
compiled function that calls MuJoCo's C API (``mj_step``, ``mj_kinematics``) directly, through
the very library the ``mujoco`` package has loaded (same process, same handle, so the same
global state: the bindings' error and warning handlers). The result is bit-identical to the
Python-driven loop (``test/sim/test_fused.py``).

Pointers: ``MjModel._address`` and ``MjData._address`` are the addresses of the C structs;
they are passed as unsigned integers of pointer width, which every 64-bit ABI MuJoCo supports
passes exactly as a pointer.

Where the library cannot be found or loaded (an unusual install), ``AVAILABLE`` is False and
the simulator keeps its Python-driven loop; nothing else changes.

Faults: ``mj_step`` raises MuJoCo errors (``mju_error``) only for a broken model or an arena
overflow, neither possible with the shipped MJCF and its 2 MB arena; an unstable state is
handled inside MuJoCo as always (a warning and a reset of the data), exactly as when called
from Python.
"""
from __future__ import annotations

import glob
import os

from numba import njit, types

from .bucket_body import bucket_body_update
from .fee_kernel import fee_update


def _library_path() -> str | None:
    import mujoco
    here = os.path.dirname(mujoco.__file__)
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        found = sorted(glob.glob(os.path.join(here, pattern)))
        if found:
            return found[0]
    return None


def _load() -> bool:
    path = _library_path()
    if path is None:
        return False
    try:
        import llvmlite.binding as llb
        llb.load_library_permanently(path)
    except Exception:   # noqa: BLE001  (any failure: keep the Python loop)
        return False
    return True


AVAILABLE = _load()

# resolved by name in the library loaded above (cacheable: no address is baked into the code)
_mj_step = types.ExternalFunction("mj_step", types.void(types.uintp, types.uintp))
_mj_kinematics = types.ExternalFunction("mj_kinematics", types.void(types.uintp, types.uintp))


@njit(cache=True)
def run_chunks(pm, pd, n_chunks, nstep, fee_on, kinematics, kargs, bargs):
    """n_chunks x (FEE update if fee_on, bucket-body update, nstep MuJoCo steps), then
    mj_kinematics if kinematics: what Simulator._physics does n_chunks times, followed by
    mujoco.mj_kinematics."""
    for _ in range(n_chunks):
        if fee_on:
            fee_update(*kargs)
        bucket_body_update(*bargs)
        for _ in range(nstep):
            _mj_step(pm, pd)
    if kinematics:
        _mj_kinematics(pm, pd)


@njit(cache=True)
def run_attack(pm, pd, nstep, fee_on, kargs, bargs, site_xpos, sid_tip, d_init, fee_dt, timeout, time0, timestep,
               qpos, wheel_qs, marks):
    """The attack drive of Simulator.reset: while the tip is short of d_init, record the drift mark
    (time, x, wheel angles) and run one chunk (run_chunks with kinematics); stop past `timeout`.
    The marks go to marks[k] (k: the chunk); the time is MuJoCo's, accumulated here as mj_step
    accumulates it (time += timestep per step). Returns (chunks run, timed out)."""
    t = 0.0
    now = time0
    k = 0
    while site_xpos[sid_tip, 0] < d_init:
        marks[k, 0] = now
        marks[k, 1] = qpos[0]
        for w in range(wheel_qs.shape[0]):
            marks[k, 2 + w] = qpos[wheel_qs[w]]
        if fee_on:
            fee_update(*kargs)
        bucket_body_update(*bargs)
        for _ in range(nstep):
            _mj_step(pm, pd)
            now += timestep
        _mj_kinematics(pm, pd)
        t += fee_dt
        k += 1
        if t > timeout:
            return k, True
    return k, False

