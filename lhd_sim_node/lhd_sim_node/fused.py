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

Where the library cannot be found or loaded, or is not the version the bindings report (an
unusual install), ``AVAILABLE`` is False, ``UNAVAILABLE_REASON`` says why (``lhd bench sim``
prints it) and the simulator keeps its Python-driven loop; nothing else changes.

Faults: ``mj_step`` reports MuJoCo errors (``mju_error``; from compiled code the process would
rather exit than raise) only for a broken model or an arena overflow, neither possible with the shipped MJCF and its 2 MB arena; an unstable state is
handled inside MuJoCo as always (a warning and a reset of the data), exactly as when called
from Python; the simulator checks for that reset after every period and after the attack drive
(whose reproduced time ``run_attack`` returns) and raises SimulationError.
"""
from __future__ import annotations

import glob
import os
import pathlib

import numba
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


def _load() -> str:
    """Load the library the ``mujoco`` package uses into llvmlite's symbol table; return '' when
    it is loaded and is the version the bindings report, else why not (UNAVAILABLE_REASON)."""
    path = _library_path()
    if path is None:
        return "no MuJoCo shared library beside the mujoco package"
    try:
        import ctypes

        import mujoco
        lib = ctypes.CDLL(path)
        lib.mj_versionString.restype = ctypes.c_char_p
        found = lib.mj_versionString().decode()
        if found != mujoco.mj_versionString():
            return f"{path} is MuJoCo {found}, the bindings are {mujoco.mj_versionString()}"
        import llvmlite.binding as llb
        llb.load_library_permanently(path)
    except Exception as e:   # noqa: BLE001  (any failure: keep the Python loop)
        return f"could not load {path}: {e}"
    return ""


def _drop_stale_cache() -> None:
    """numba keys the disk cache of the loops below on this file's stamp alone, but they hold
    compiled copies of fee_kernel / bucket_body code (and fee.py, kinematics.py constants): when
    any of those sources changed since the cache was written, the cached loops are removed so that
    numba compiles them again."""
    import hashlib
    import numba.core.config as ncfg
    here = os.path.dirname(os.path.abspath(__file__))
    deps = [os.path.join(here, f) for f in ("fused.py", "fee_kernel.py", "bucket_body.py", "fee.py", "mjcf.py")]
    try:
        from lhd_loading_ros.task import kinematics
        deps.append(kinematics.__file__)
        digest = hashlib.sha256(b"".join(pathlib.Path(f).read_bytes() for f in deps)).hexdigest()
        dirs = [os.path.join(here, "__pycache__")] + ([ncfg.CACHE_DIR] if ncfg.CACHE_DIR else [])
        for d in dirs:
            stamp = os.path.join(d, "fused.deps")
            if os.path.isdir(d) and (not os.path.isfile(stamp) or pathlib.Path(stamp).read_text() != digest):
                for f in glob.glob(os.path.join(d, "**", "fused.run_*"), recursive=True):
                    os.remove(f)
                with open(stamp, "w") as fh:
                    fh.write(digest)
    except OSError:
        pass     # a read-only install: nothing cached there either


_drop_stale_cache()

# NUMBA_DISABLE_JIT: the external functions would be no-ops from plain Python
UNAVAILABLE_REASON = "NUMBA_DISABLE_JIT is set" if numba.config.DISABLE_JIT else _load()
AVAILABLE = not UNAVAILABLE_REASON

# resolved by name in the library loaded above (cacheable: no address is baked into the code)
_mj_step = types.ExternalFunction("mj_step", types.void(types.uintp, types.uintp))
_mj_kinematics = types.ExternalFunction("mj_kinematics", types.void(types.uintp, types.uintp))


@njit(cache=True)    # a stale cache is dropped at import (_drop_stale_cache)
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
def run_chunks_marked(pm, pd, n_chunks, nstep, fee_on, kinematics, kargs, bargs, time0, timestep, qpos, wheel_qs,
                      marks):
    """run_chunks, recording after each chunk the drift mark (time, x, wheel angles) in marks[k] (k: the
    chunk): the machine's travel at the chunk grain, for a drift window that does not begin with the
    control period (LhdSimulator.drift_flag). The same physics as run_chunks, step for step; the time is
    MuJoCo's, accumulated as mj_step accumulates it."""
    now = time0
    for k in range(n_chunks):
        run_chunks(pm, pd, 1, nstep, fee_on, False, kargs, bargs)
        for _ in range(nstep):
            now += timestep
        marks[k, 0] = now
        marks[k, 1] = qpos[0]
        for w in range(wheel_qs.shape[0]):
            marks[k, 2 + w] = qpos[wheel_qs[w]]
    if kinematics:
        _mj_kinematics(pm, pd)


@njit(cache=True)
def run_attack(pm, pd, nstep, fee_on, kargs, bargs, site_xpos, sid_tip, d_init, fee_dt, timeout, time0, timestep,
               qpos, wheel_qs, marks):
    """The attack drive of Simulator.reset: while the tip is short of d_init, record the drift mark
    (time, x, wheel angles) and run one chunk (run_chunks with kinematics); stop past `timeout`.
    The marks go to marks[k] (k: the chunk); the time is MuJoCo's, accumulated here as mj_step
    accumulates it (time += timestep per step). Returns (chunks run, timed out, the time reproduced);
    the caller compares that time with MuJoCo's, which an instability reset (mj_resetData) zeroes."""
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
            return k, True, now
    return k, False, now

