"""The DDPG training loop: collect, update, evaluate, checkpoint, export.

A run directory holds
  run.json          arguments, config hash, DDPG settings
  evals.csv         one row per evaluation (every eval_every steps): AR, AML, AFF, ASL, ...
  episodes.csv      one row per training episode (return, loaded mass, outcome, noise scale)
  checkpoint.pt     agent, optimisers, replay buffer, RNG states (tensors and plain values
                    only: loaded with torch.load(weights_only=True)); written every
                    checkpoint_every steps, atomically
  best/             exported actor with the best evaluation so far (ASL, then success, then AR)
  final/            exported actor at the end of training
With the tilt penalty ramped in (task.r_tilt_ramp_after_success > 0, TiltRamp), the replay keeps the
penalty apart and weights it when sampled; run.json and the checkpoint hold the ramp's state.
With the slope curriculum (training.slope_curriculum, learning/curriculum.py) each training pile's
slope is drawn from bins weighted by their recent failures; curriculum.csv holds the draw's
probabilities at every evaluation, the checkpoint its state.
Interrupted runs resume from checkpoint.pt: the agent, replay and noise continue exactly; the
episode in progress is dropped and starts again (training episode k always uses the pile of
seed (run seed, k), so with one environment the sequence of piles is the same with or without a
resume; with several sim nodes the episodes in progress start again first, each index once).
A run resumed with fewer steps than it has is refused; with as many, it is complete.
A run started over (resume=False, `lhd train --no-resume`) first moves the previous run's files
(checkpoints, best/, final/, run.json, the logs) into previous_<UTC time>/ of the folder: nothing is deleted.
"""
from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import torch

from lhd_loading_ros.task.config import TILT_SCHEDULE_KEYS, TRAINING_SCHEDULE_KEYS, config_hash, load_config
from lhd_loading_ros.task.metrics import result_from_status
from lhd_loading_ros.learning.curriculum import CurriculumConfig, SlopeCurriculum
from lhd_loading_ros.learning.demonstrations import DemoConfig
from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig, OUNoise, ReplayBuffer, TiltRamp, lr_scale, noise_scale
from lhd_loading_ros.learning.evaluate import evaluate
from lhd_loading_ros.learning.export import export_actor

EVAL_FIELDS = ("step", "ar", "aml", "aff", "asl", "success_rate", "end_zone_rate", "elapsed_s",
               "front_drift_pct", "rear_drift_pct", "noise_scale", "critic_loss", "q_mean", "episodes_done",
               "wall_s", "eval_wall_s")
EPISODE_FIELDS = ("episode", "step", "return", "loaded", "outcome", "steps", "alpha_deg", "material", "noise_scale",
                  "source", "success", "driver", "r_success")
# success: the paper's test (SL >= 1), what the slope curriculum counts (with training.slope_curriculum_reward_test
# only together with r_success > 0, the reward's success term at the last step); driver: "actor", or
# "scripted crowd c" for a demonstration (training.demo_share, learning/demonstrations.py)
ENV_KINDS = ("local", "ros")


def episode_seed(run_seed: int, k: int, offset: int = 0) -> int:
    """The seed of training episode k of run `run_seed`: offset + run_seed * 1,000,003 + k (mod 2^31 - 1).
    With training.episode_seed_offset 0 (every run before 2026-11-29, twelfth session) run seeds 1, 2 and 3
    drew their first ~115 piles from the evaluation seeds 1,000,000, 2,000,000 and 3,000,000 + i; the
    default file's offset 1,000,000,000 keeps run seeds below ~1,100 above every evaluation seed."""
    return (int(offset) + int(run_seed) * 1_000_003 + int(k)) % (2**31 - 1)


class _Progress:
    def __init__(self, label: str, total: int, enabled: bool):
        self.label, self.total, self.enabled = label, total, enabled
        self.t0 = time.perf_counter()
        self.start_step = None
        self.last = 0.0
        self.eval_text = "no evaluation yet"

    def update(self, step: int, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if self.start_step is None:
            self.start_step, self.t0 = step, now
        if not force and now - self.last < 1.0:
            return
        self.last = now
        rate = (step - self.start_step) / max(now - self.t0, 1e-9)
        eta = (self.total - step) / rate if rate > 0 else float("inf")
        frac = step / self.total
        bar = "#" * int(20 * frac) + "-" * (20 - int(20 * frac))
        eta_s = "--:--" if not math.isfinite(eta) else f"{int(eta // 60)}:{int(eta % 60):02d}"
        sys.stderr.write(f"\r{self.label} [{bar}] {step:,}/{self.total:,} {rate:,.0f} steps/s ETA {eta_s} | "
                         f"{self.eval_text}   ")
        sys.stderr.flush()

    def close(self):
        if self.enabled:
            sys.stderr.write("\n")


def _tensorboard(out: Path):
    try:
        from torch.utils.tensorboard import SummaryWriter  # needs the optional tensorboard package
    except Exception:
        return None
    return SummaryWriter(str(out / "tb"))


def _append_csv(path: Path, fields, row: dict) -> None:
    new = not path.exists()
    with open(path, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        if new:
            w.writeheader()
        w.writerow({k: row.get(k, "") for k in fields})


def _truncate_csv(path: Path, key: str, limit: int, fields=None) -> None:
    """Drop rows written after the checkpoint we resume from (their steps will be redone).
    fields: the columns the run writes now; a file of an older layout gets them (blank in its
    old rows), so that the rows appended after the resume match its header."""
    if not path.exists():
        return
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
        header = list(reader.fieldnames or [])
    fields = list(fields) if fields is not None else header
    fields += [k for k in header if k not in fields]
    kept = [r for r in rows if int(float(r[key])) <= limit]
    if not fields:
        path.unlink()                  # nothing in it: _append_csv writes the header again
        return
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, restval="")
        w.writeheader()
        w.writerows(kept)


# what a run leaves in its folder (the module docstring), moved aside by --no-resume (set_aside)
RUN_FILES = ("checkpoint.pt", "checkpoint.pt.tmp", "run.json", "evals.csv", "episodes.csv", "curriculum.csv", "best",
             "final", "tb")


def set_aside(out: Path) -> Path | None:
    """Move a previous run's files (RUN_FILES and checkpoint_step*.pt) out of `out` into
    out/previous_<UTC time>/ (a review, 2026-11-30: --no-resume left the old checkpoints, actors and
    run.json beside the new run's logs). Returns that folder, None when there was nothing to move."""
    names = [n for n in RUN_FILES if (out / n).exists()] + sorted(p.name for p in out.glob("checkpoint_step*.pt"))
    if not names:
        return None
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    dest, k = out / f"previous_{stamp}", 1
    while dest.exists():
        k += 1
        dest = out / f"previous_{stamp}_{k}"
    dest.mkdir()
    for n in names:
        os.replace(out / n, dest / n)
    return dest


def schedule_of(cfg: dict) -> dict:
    """The training schedule left out of the config hash on purpose (TRAINING_SCHEDULE_KEYS, TILT_SCHEDULE_KEYS:
    what --branch-from may change): kept in the checkpoint, so that a plain resume under another one is refused.
    Keys that mean nothing while what they tune is off (a ramp's steps without the ramp, ...) are left out."""
    t, k = cfg.get("training", {}), cfg.get("task", {})
    out = {**{f"training.{n}": t.get(n) for n in TRAINING_SCHEDULE_KEYS},
           **{f"task.{n}": k.get(n) for n in TILT_SCHEDULE_KEYS}}
    off = set()
    if not int(t.get("slope_curriculum", 0) or 0):
        off |= {f"training.{n}" for n in TRAINING_SCHEDULE_KEYS if n.startswith("slope_curriculum_")}
    if float(t.get("lr_final_scale", 1.0)) >= 1.0:
        off.add("training.lr_decay_from")
    if float(t.get("demo_share", 0.0) or 0.0) <= 0.0:
        off |= {f"training.{n}" for n in TRAINING_SCHEDULE_KEYS if n.startswith("demo_") and n != "demo_share"}
    elif float(t.get("demo_bc", 0.0) or 0.0) <= 0.0:
        off.add("training.demo_bc_return_filter")
    if float(k.get("r_tilt_per_deg", 0.0) or 0.0) <= 0.0:
        off |= {"task.r_tilt_ramp_after_success", "task.r_tilt_ramp_steps", "task.r_tilt_ramp_pitch_margin"}
    elif float(k.get("r_tilt_ramp_after_success", 0.0) or 0.0) <= 0.0:
        off |= {"task.r_tilt_ramp_steps", "task.r_tilt_ramp_pitch_margin"}
    return {n: v for n, v in out.items() if n not in off}


def load_checkpoint(ckpt: Path) -> dict:
    """torch.load of a checkpoint; ValueError saying what to do when the file is unreadable (truncated, empty)."""
    import pickle

    try:
        return torch.load(ckpt, weights_only=True)
    except (OSError, EOFError, RuntimeError, ValueError, pickle.UnpicklingError) as exc:
        raise ValueError(f"{ckpt} unreadable ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else 'empty'}):"
                         " remove it or use --no-resume") from None


def _rank(ev: dict) -> tuple:
    return (round(ev["asl"], 6), round(ev["success_rate"], 6), ev["ar"])


def _branch(src: Path, out: Path, ckpt: Path, log) -> None:
    """Start run directory `out` from the kept checkpoint `src` (see train's branch_from): copy it to
    out/checkpoint.pt with the source run's evals / episodes / curriculum logs (the resume cuts them
    at its step). A directory that already has a checkpoint goes on from it (the branch was made)."""
    if ckpt.exists():
        log(f"{out} already has a checkpoint; going on from it (not branching again from {src})")
        return
    if not src.is_file():
        raise ValueError(f"branch source {src} does not exist: expected a kept checkpoint "
                         "(checkpoint_step<N>.pt, written by `lhd train --keep-checkpoint N`)")
    for f in ("evals.csv", "episodes.csv", "curriculum.csv"):
        if (src.parent / f).is_file():
            shutil.copyfile(src.parent / f, out / f)
    shutil.copyfile(src, ckpt)
    log(f"branched {out} from {src}")


@contextlib.contextmanager
def run_dir_lock(out: Path):
    """An exclusive lock on a run directory for one trainer (flock on out/.train.lock, released when the
    process ends however it ends): a second `lhd train` into the same directory, e.g. the same command
    run again while an earlier one's children still train (a review, 2026-11-29: two trainers then wrote
    one episodes.csv), is refused with the holder's pid."""
    import fcntl

    out.mkdir(parents=True, exist_ok=True)
    f = open(out / ".train.lock", "a+")
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        f.seek(0)
        who = f.read().strip() or "pid unknown"
        f.close()
        raise ValueError(f"another lhd train is writing {out} ({who}): stop it first, or train into another --out") \
            from None
    try:
        f.seek(0)
        f.truncate()
        f.write(f"pid {os.getpid()}\n")
        f.flush()
        yield
    finally:
        fcntl.flock(f, fcntl.LOCK_UN)
        f.close()


def train(variant: str, seed: int, out, *args, **kwargs) -> dict:
    """`_train` (below) holding run_dir_lock(out) for the whole run."""
    out = Path(out)
    with run_dir_lock(out):
        return _train(variant, seed, out, *args, **kwargs)


def _train(variant: str, seed: int, out, steps: int | None = None, config=None, resume: bool = True,
          progress: bool = True, eval_episodes: int | None = None, eval_every: int | None = None,
          checkpoint_every: int | None = None, log=print, randomize: bool = False, env_kind: str = "local",
          namespaces: list[str] | None = None, ros_timeout: float = 30.0, keep_checkpoints=(),
          branch_from=None) -> dict:
    """Train one DDPG agent; return the last evaluation (dict). See the module docstring.
    randomize: domain randomisation (config section `randomization`, task/randomization.py) in
    training and in the periodic evaluations; it enters the config hash of the run and its actor.
    env_kind "local": the in-process LhdLoading-v0; "ros": one lockstep sim node per namespace in
    `namespaces` (lhd_sim_node.ros_env.SimNodePool), stepped together, each transition into the
    one replay buffer (one update per transition, as with one environment); the evaluations stay
    in-process. run.json and episodes.csv (`source`) say which node gave what.
    keep_checkpoints: steps at which a copy of the checkpoint is kept as checkpoint_step<N>.pt
    (the checkpoint itself is overwritten every checkpoint_every steps).
    branch_from: a kept checkpoint (checkpoint_step<N>.pt) of the same variant, seed and config
    hash, which a new run directory `out` starts from, with the source's logs up to step N; the
    run then goes on like a resumed one under `config`, whose training schedule (not in the hash:
    demonstrations, learning rates, ...) may differ. A paired comparison of a late change costs
    only the steps after N (training is deterministic per seed; a resume restarts the episodes
    in progress at the checkpoint, so the branch is not bit-identical to an uninterrupted run)."""
    from lhd_sim_node.env import LhdLoadingEnv   # the simulator is only needed to train

    cfg = config if isinstance(config, dict) else load_config(config)
    if randomize:
        cfg = {**cfg, "randomization": {**cfg["randomization"], "enabled": 1}}
    if not cfg["randomization"]["enabled"]:
        # without randomisation every episode is told the true slope: these keys would do nothing, silently
        on = [k for k, v in (("training.demo_told_high", cfg["training"].get("demo_told_high", 0.0) > 0.0),
                             ("task.reward_zones_from_pile", cfg["task"].get("reward_zones_from_pile", 0))) if v]
        if on:
            raise ValueError(f"{' and '.join(on)} act only on episodes whose slope is told wrong, and without domain "
                             "randomisation no episode is: train with --randomize (or randomization.enabled: 1), "
                             "or set them to 0")
    dc = DdpgConfig.from_config(cfg)
    seed_offset = int(cfg["training"].get("episode_seed_offset", 0))   # where the episode seeds start (episode_seed)
    over = {k: v for k, v in (("total_steps", steps), ("eval_episodes", eval_episodes),
                               ("eval_every", eval_every), ("checkpoint_every", checkpoint_every)) if v is not None}
    if over:
        dc = DdpgConfig(**{**dc.__dict__, **over})
    if dc.total_steps < 1:
        raise ValueError(f"steps must be >= 1, got {dc.total_steps}")
    if dc.total_steps <= dc.learning_starts:
        # said, not refused: short runs test the loop's mechanics; but the actor written is the
        # untrained one and must not pass for a trained one (a review)
        log(f"warning: {dc.total_steps:,} steps are not more than training.learning_starts = {dc.learning_starts:,}: "
            "no update will run, and the actor written is the untrained one")

    if dc.lr_final_scale < 1.0 and dc.lr_decay_from >= dc.total_steps:
        raise ValueError(f"training.lr_decay_from = {dc.lr_decay_from:,} is not before the run's last step "
                         f"({dc.total_steps:,}): the learning rates would never fall although lr_final_scale = "
                         f"{dc.lr_final_scale:g} says they should; set lr_decay_from below the steps, or "
                         "lr_final_scale to 1")
    torch.set_num_threads(cfg["training"]["torch_threads"])
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    chash = config_hash(cfg)

    if env_kind not in ENV_KINDS:
        raise ValueError(f"env must be one of {ENV_KINDS}, got {env_kind!r}")
    task_cfg = cfg["task"]
    mass_margin = float(task_cfg.get("r_success_mass_margin_kg", 0.0))
    ramp = TiltRamp(float(task_cfg.get("r_tilt_ramp_after_success", 0.0)) if float(task_cfg.get("r_tilt_per_deg", 0.0)) > 0
                    else 0.0, int(task_cfg.get("r_tilt_ramp_steps", 0)),
                    pitch_margin=bool(int(task_cfg.get("r_tilt_ramp_pitch_margin", 0))))
    if ramp.pitch_margin and not (ramp.enabled and (float(task_cfg.get("r_success_pitch_margin_deg", 0.0)) > 0
                                                    or mass_margin > 0)):
        raise ValueError("task.r_tilt_ramp_pitch_margin = 1 ramps r_success's margins in with the tilt penalty: it "
                         "needs task.r_tilt_per_deg > 0, task.r_tilt_ramp_after_success > 0 and "
                         "task.r_success_pitch_margin_deg > 0 or task.r_success_mass_margin_kg > 0 (got "
                         f"{task_cfg.get('r_tilt_per_deg')}, {task_cfg.get('r_tilt_ramp_after_success')}, "
                         f"{task_cfg.get('r_success_pitch_margin_deg')}, {task_cfg.get('r_success_mass_margin_kg')})")
    if ramp.enabled and env_kind != "local":
        raise ValueError("task.r_tilt_ramp_after_success > 0 (the tilt penalty ramped in) needs the in-process "
                         "environment: the sim nodes' transitions do not give the reward's terms apart; set it "
                         "to 0 or train with --env local")
    if (env_kind != "local" and int(cfg["randomization"].get("enabled", 0))
            and int(cfg["randomization"].get("zones_at_nominal_density", 0))):
        raise ValueError("randomization.zones_at_nominal_density = 1 (the end-zone node's zones in training) needs the "
                         "in-process environment: the sim nodes judge and publish the pile's own zones; set it to 0 "
                         "or train with --env local")
    cur_cfg = CurriculumConfig.from_training(cfg["training"])
    if cur_cfg is not None and env_kind != "local":
        raise ValueError("training.slope_curriculum = 1 draws each training pile's slope in the learner: it needs the "
                         "in-process environment (the sim nodes draw their own piles); set it to 0 or train with "
                         "--env local")
    demos = DemoConfig.from_training(cfg["training"])
    if demos is not None and env_kind != "local":
        raise ValueError("training.demo_share > 0 drives some training episodes with the scripted maneuver, which reads "
                         "the in-process simulator's state: it needs the in-process environment; set it to 0 or "
                         "train with --env local")
    if dc.demo_bc > 0.0 and demos is None:
        raise ValueError(f"training.demo_bc = {dc.demo_bc:g} clones the scripted demonstrations' actions, but "
                         "training.demo_share = 0 gives none: set demo_share > 0 (e.g. 0.2), or demo_bc to 0")
    demo_crowd: dict = {}              # slot -> the crowd of the demonstration it runs (absent: the actor drives)
    ep_cfg = cfg["paper"]["episode"]
    curriculum = (SlopeCurriculum(float(ep_cfg["alpha_min_deg"]), float(ep_cfg["alpha_max_deg"]), cur_cfg)
                  if cur_cfg is not None else None)
    eval_env = LhdLoadingEnv(variant, cfg)     # evaluations in-process, on the learner's machine
    if env_kind == "ros":
        from lhd_sim_node.ros_env import SimNodePool

        if not namespaces:
            raise ValueError("env 'ros' needs the sim nodes' namespaces, e.g. ['/sim0', '/sim1']")
        pool = SimNodePool(list(namespaces), variant, cfg, timeout=ros_timeout)
        sources = [link.label for link in pool.links]

        def reset_slot(i: int, seed_k: int):
            return pool.reset(i, seed_k).obs

        def step_slots(actions: dict) -> dict:
            out_ = {}
            for i, (t, end) in pool.step(actions).items():
                info_ = {"outcome": end["state"] if (end is not None and t.terminated) else "running"}
                if end is not None:
                    info_["episode_result"] = result_from_status(end)
                out_[i] = (t.obs, t.reward, t.terminated, t.truncated, info_)
            return out_
    else:
        if namespaces:
            raise ValueError("namespaces are for env 'ros' (sim nodes); the in-process environment has none")
        pool = None
        env = LhdLoadingEnv(variant, cfg)
        sources = ["local"]

        def reset_slot(i: int, seed_k: int):
            opts = {}
            if curriculum is not None:
                # the slope from the curriculum, on its own stream of the episode's seed
                opts["slope_deg"] = curriculum.draw(np.random.default_rng([seed_k, 0x5C]))
            crowd = demos.draw(seed_k, step) if demos is not None else None
            if crowd is None:
                demo_crowd.pop(i, None)
            else:
                demo_crowd[i] = crowd
            # the redraw of a pile whose attack stalls lives with the environment (the sim node's too)
            from lhd_sim_node.env import reset_or_redraw

            out_ = reset_or_redraw(env, seed_k, opts, log)
            if crowd is None and demos is not None:
                # training.demo_told_high: an episode told too steep is a demonstration as well
                told_high = demos.told_high_crowd(seed_k, step, env.told_slope_deg - math.degrees(env.sim.pile.alpha))
                if told_high is not None:
                    demo_crowd[i] = told_high
            if i not in demo_crowd and demos is not None and demos.failing > 0.0 and curriculum is not None:
                # training.demo_failing_share: an episode on a slope bin the actor still fails is a demonstration
                # with probability demo_failing_share x the bin's failure rate (the curriculum's own counts)
                failing = demos.failing_crowd_on(curriculum, seed_k, step, math.degrees(env.sim.pile.alpha))
                if failing is not None:
                    demo_crowd[i] = failing
            if (i in demo_crowd and demos is not None and demos.where_teacher_wins and curriculum is not None
                    and not curriculum.teacher_wins(math.degrees(env.sim.pile.alpha))):
                # training.demo_where_teacher_wins: no demonstration on a bin where the actor does better
                demo_crowd.pop(i)
            return out_

        from lhd_sim_node.simulator import SimulationError

        def step_slots(actions: dict) -> dict:
            try:
                return {0: env.step(actions[0])}
            except SimulationError as e:      # MuJoCo reset an unstable state: no transition, the episode ends
                return {0: e}

    slots = range(len(sources))
    agent = DdpgAgent(dc, seed)
    # the tilt term apart while it is ramped in; the demonstration flag for behaviour cloning
    replay = ReplayBuffer(dc.replay_size, aux=ramp.enabled, demo=dc.demo_bc > 0.0,
                          demo_return=dc.demo_bc > 0.0 and bool(dc.demo_bc_return_filter))
    # training.demo_bc_return_filter: a running demonstration's rows (ticket, r, aux), whose returns are
    # written into the replay when it ends (an aborted one's never: its rows are not cloned)
    demo_rows: dict = {}
    rng = np.random.default_rng(seed)
    noise = OUNoise(3, dc.ou_mu, dc.ou_sigma, dc.ou_theta, dc.ou_dt, rng)
    # one OU process per source (the first draws from the run's rng, as with one environment)
    noises = [noise] + [OUNoise(3, dc.ou_mu, dc.ou_sigma, dc.ou_theta, dc.ou_dt, np.random.default_rng([seed, i]))
                        for i in slots[1:]]
    step, episode, best, wall_before = 0, 0, None, 0.0
    contributed = {src: 0 for src in sources}

    ckpt = out / "checkpoint.pt"
    keep = sorted({int(k) for k in keep_checkpoints})
    if any(k < 1 or k > dc.total_steps or k % dc.checkpoint_every for k in keep):
        raise ValueError(f"checkpoints to keep {keep}: expected steps in 1..{dc.total_steps:,} that are multiples of "
                         f"checkpoint_every ({dc.checkpoint_every:,})")
    if branch_from is not None:
        _branch(Path(branch_from), out, ckpt, log)
        resume = True
    schedule = schedule_of(cfg)
    if resume and ckpt.exists():
        st = load_checkpoint(ckpt)
        if st["variant"] != variant or st["seed"] != seed:
            raise ValueError(f"{ckpt} belongs to variant {st['variant']} seed {st['seed']}, not {variant} seed "
                             f"{seed}; use another --out or remove the checkpoint")
        if st["config_hash"] != chash:
            raise ValueError(f"{ckpt} was trained with another parameter file (config hash {st['config_hash'][:12]} "
                             f"!= {chash[:12]}); use another --out or the same config")
        agent.load_state_dict(st["agent"])
        replay.load_state_dict(st["replay"])
        if curriculum is not None:
            if not st.get("slope_curriculum"):
                raise ValueError(f"{ckpt} was trained without training.slope_curriculum: resume with it off, or use "
                                 "another --out")
            curriculum.load_state_dict(json.loads(st["slope_curriculum"]))
        elif st.get("slope_curriculum"):
            raise ValueError(f"{ckpt} was trained with training.slope_curriculum: resume with it on, or use another "
                             "--out")
        if "r_success_mass_margin_kg" in st and float(st["r_success_mass_margin_kg"]) != mass_margin:
            # also refused for a branch: the replay keeps each transition's cut of r_success as the margin
            # then in force made it (its success_margin_cut column), so a new margin would train on both
            raise ValueError(f"{ckpt} was trained with task.r_success_mass_margin_kg = "
                             f"{float(st['r_success_mass_margin_kg']):g}, this config has {mass_margin:g}: resume "
                             + ("or branch with the same margin (the replay's rewards were cut with it), or train "
                                "another margin from the start into another --out" if branch_from is not None else
                                "with the same margin or use another --out"))     # (checkpoints before the key: not checked)
        if ramp.enabled and st.get("tilt_ramp"):      # (the replay's columns already refused a ramp switched on/off)
            ramp.load_state_dict(json.loads(st["tilt_ramp"]))
        # after the checks above, whose messages say more of their own keys
        if branch_from is None and st.get("schedule"):      # (checkpoints before the key: not checked)
            was = json.loads(st["schedule"])
            # a key the checkpoint predates had its default then (OPTIONAL_DEFAULTS): the same schedule
            from lhd_loading_ros.task.config import OPTIONAL_DEFAULTS
            was = {**{f"{sec}.{k}": v for (sec, k), v in OPTIONAL_DEFAULTS.items() if f"{sec}.{k}" in schedule}, **was}
            changed = [k for k in sorted(set(was) | set(schedule)) if was.get(k) != schedule.get(k)]
            if changed:     # else run.json and the actor's trained_with would claim the new schedule for the whole run
                raise ValueError(
                    f"{ckpt} was trained under another training schedule: "
                    + ", ".join(f"{k} {was.get(k)!r} -> {schedule.get(k)!r}" for k in changed)
                    + "; resume with the schedule it had, or go on under the new one as a branch of a kept checkpoint "
                    "into another --out (lhd train --branch-from RUN/checkpoint_step<N>.pt, docs/training.md)")
        rng.bit_generator.state = json.loads(st["rng"])
        noise.x[:] = st["noise_x"].numpy()
        more = st.get("noise_more")
        if more is not None:           # the other sources' OU processes (several sim nodes)
            for i, x in zip(slots[1:], more.numpy()):
                noises[i].x[:] = x
        step, episode = int(st["step"]), int(st["episode"])
        # episodes in progress at the checkpoint start again first, on their piles; then new ones
        pending = json.loads(st["pending"]) if st.get("pending") else [episode]
        next_episode = int(st["next_episode"]) if "next_episode" in st else episode + 1
        for k, v in (json.loads(st["contributed"]) if st.get("contributed") else {}).items():
            contributed[k] = contributed.get(k, 0) + int(v)
        lr_total = int(st.get("lr_total_steps", 0))
        if (dc.lr_final_scale < 1.0 and lr_total and lr_total != dc.total_steps
                and step > dc.lr_decay_from):
            raise ValueError(f"{ckpt} is {step:,} steps into a learning-rate decay that runs to step {lr_total:,}; "
                             f"going on to {dc.total_steps:,} would move the schedule (the rates would jump back "
                             f"up): give --steps {lr_total:,}, or start another --out")
        if step > dc.total_steps:
            raise ValueError(f"{out} already has {step:,} steps, more than the {dc.total_steps:,} asked; give --steps "
                             f">= {step:,} to go on, or another --out")
        best = json.loads(st["best"]) if st["best"] else None
        wall_before = float(st["wall_s"])
        _truncate_csv(out / "evals.csv", "step", step, EVAL_FIELDS)
        _truncate_csv(out / "episodes.csv", "step", step, EPISODE_FIELDS)
        if (out / "curriculum.csv").exists():
            _truncate_csv(out / "curriculum.csv", "step", step)
        log(f"resumed {out} at step {step:,} (episode {episode})")
    else:
        pending, next_episode = [], 0
        if not resume:                 # --no-resume: the old run's files moved aside, nothing deleted
            aside = set_aside(out)
            if aside is not None:
                log(f"--no-resume: moved the previous run's files to {aside}/ (nothing deleted); starting over")
        for f in ("evals.csv", "episodes.csv", "curriculum.csv"):
            (out / f).unlink(missing_ok=True)

    def write_run_json() -> None:
        (out / "run.json").write_text(json.dumps({
            "variant": variant, "seed": seed, "config_hash": chash, "ddpg": dc.to_dict(),
            "torch": torch.__version__, "command": sys.argv, "env": env_kind, "sources": sources,
            "transitions_by_source": contributed,
            **({"tilt_ramp": ramp.state_dict()} if ramp.enabled else {}),
            **({"demonstrations": demos.to_dict()} if demos is not None else {}),
            **({"slope_curriculum": {**cur_cfg.to_dict(), "probabilities": curriculum.probabilities().round(4).tolist()}}
               if curriculum is not None else {})}, indent=2) + "\n")

    write_run_json()

    meta_base = {"variant": variant, "seed": seed, "config_hash": chash, "ddpg": dc.to_dict()}

    def export(name: str, ev: dict) -> None:
        # with the ramp: the tilt penalty's weight this actor was trained to (1: the whole penalty;
        # 0: the ramp never began, the actor never met the penalty), on its card
        ramp_meta = ({"tilt_ramp": {**ramp.state_dict(), "weight": ramp.weight(step)}} if ramp.enabled else {})
        export_actor(out / name, agent.actor, cfg, {**meta_base, "steps": step, "evaluation": ev, **ramp_meta})

    def save_checkpoint() -> None:
        st = {"variant": variant, "seed": seed, "config_hash": chash, "step": step, "episode": episode,
              "agent": agent.state_dict(), "replay": replay.state_dict(),
              "rng": json.dumps(rng.bit_generator.state), "noise_x": torch.from_numpy(noise.x.copy()),
              "noise_more": torch.from_numpy(np.array([noises[i].x for i in slots[1:]], dtype=np.float64).reshape(-1, 3)),
              "pending": json.dumps([slot_episode[i] for i in slots] + queue), "next_episode": started,
              "contributed": json.dumps(contributed),
              "tilt_ramp": json.dumps(ramp.state_dict()) if ramp.enabled else "",
              "slope_curriculum": json.dumps(curriculum.state_dict()) if curriculum is not None else "",
              "best": json.dumps(best) if best else "", "wall_s": wall_before + time.perf_counter() - t0,
              # the step the learning-rate decay runs to (0: no decay): a resume must not move it
              "lr_total_steps": dc.total_steps if dc.lr_final_scale < 1.0 else 0,
              # r_success's mass margin (never in the config hash): a resume must keep it
              "r_success_mass_margin_kg": mass_margin,
              # the training schedule (never in the hash either): a plain resume must keep it (--branch-from may not)
              "schedule": json.dumps(schedule, sort_keys=True)}
        tmp = out / "checkpoint.pt.tmp"
        torch.save(st, tmp)
        if step in keep:
            shutil.copyfile(tmp, out / f"checkpoint_step{step}.pt")
        os.replace(tmp, ckpt)

    tb = _tensorboard(out)
    bar = _Progress(f"{variant} seed {seed}", dc.total_steps, progress)
    t0 = time.perf_counter()
    # episode indices: those in progress at a checkpoint start again first (with one source, the
    # one dropped by an interruption: the same pile), then new ones from next_episode on; every
    # index is used once, whatever order the sources finish in
    queue, started = list(pending), next_episode

    def next_index() -> int:
        nonlocal started
        if queue:
            return queue.pop(0)
        started += 1
        return started - 1

    obs, slot_episode = {}, {}
    for i in slots:
        slot_episode[i] = next_index()
        obs[i] = reset_slot(i, episode_seed(seed, slot_episode[i], seed_offset))
    ep_ret = {i: 0.0 for i in slots}
    last_eval, closs, qmean = None, float("nan"), float("nan")
    if step >= dc.total_steps:         # resumed at the end: the run is complete
        meta = out / "final" / "policy.json"
        if meta.is_file() and json.loads(meta.read_text()).get("evaluation"):
            log(f"{out} is complete ({step:,} steps); nothing to do")
            if pool is not None:
                pool.close()
            return json.loads(meta.read_text())["evaluation"]
        ev = evaluate(eval_env, agent.actor_numpy(), dc.eval_episodes, dc.eval_seed, cfg["task"]["bucket_capacity"],
                      breakdown=False)
        last_eval = {k: ev[k] for k in EVAL_FIELDS if k in ev}
        last_eval["step"] = step
    bucket = cfg["task"]["bucket_capacity"]
    try:
        while step < dc.total_steps:
            scale = noise_scale(step, dc.noise_decay_steps, dc.noise_final_scale, dc.noise_after_decay)
            acts = {i: (demos.action(env, demo_crowd[i]) if i in demo_crowd
                        else np.clip(agent.act(obs[i]) + scale * noises[i].sample(), -1.0, 1.0))
                    for i in slots[: dc.total_steps - step]}
            results = step_slots(acts)
            for i, a in acts.items():        # each source's transition in turn, as one environment's
                if isinstance(results[i], Exception):
                    # MuJoCo found the state unstable and reset it (SimulationError): the step has no next
                    # state to learn from, so it gives no transition; the episode ends as `aborted` in
                    # episodes.csv and the next one starts. It must not end a run of hours
                    log(f"{variant} seed {seed}: episode {slot_episode[i]} aborted after {env.steps} steps "
                        f"({results[i]}); no transition from it, the next episode starts")
                    _append_csv(out / "episodes.csv", EPISODE_FIELDS, {
                        "episode": slot_episode[i], "step": step, "return": f"{ep_ret[i]:.3f}",
                        "loaded": f"{env.sim.loaded_mass:.3f}", "outcome": "aborted", "steps": env.steps,
                        "alpha_deg": f"{math.degrees(env.sim.pile.alpha):.2f}", "material": env.sim.material,
                        "noise_scale": f"{scale:.4f}", "source": sources[i], "success": 0,
                        "driver": f"scripted crowd {demo_crowd[i]:.3f}" if i in demo_crowd else "actor"})
                    episode += 1
                    ep_ret[i] = 0.0
                    noises[i].reset()
                    demo_rows.pop(i, None)       # an aborted demonstration's rows keep G = -inf: never cloned
                    slot_episode[i] = next_index()
                    obs[i] = reset_slot(i, episode_seed(seed, slot_episode[i], seed_offset))
                    continue
                obs2, r, term, trunc, info = results[i]
                aux = 0.0
                if ramp.enabled:             # the tilt term (and a ramped margin's cut) apart, weighted when sampled
                    aux = float(info["terms"].get("tilt", 0.0))
                    if ramp.pitch_margin:
                        aux += float(info["success_margin_cut"])
                    ticket = replay.add(obs[i], a, r - aux, term, obs2, aux=aux, demo=replay.demo and i in demo_crowd)
                    replay.aux_weight = ramp.weight(step)
                else:
                    ticket = replay.add(obs[i], a, r, term, obs2, demo=replay.demo and i in demo_crowd)
                if replay.demo_return and i in demo_crowd:
                    demo_rows.setdefault(i, []).append((ticket, r - aux, aux))
                contributed[sources[i]] += 1
                ep_ret[i] += r
                step += 1
                if replay.size >= dc.learning_starts:
                    if dc.lr_final_scale < 1.0:    # training.lr_final_scale: the late learning rates
                        agent.set_lr_scale(lr_scale(step, dc.lr_decay_from, dc.total_steps, dc.lr_final_scale))
                    err, q = agent.update(*replay.sample(dc.batch_size, agent.gen))
                obs[i] = obs2
                if term or trunc:
                    res = info["episode_result"]
                    r_succ = float(info.get("terms", {}).get("success", 0.0)) if term else 0.0
                    demo = i in demo_crowd
                    if demo_rows.get(i):     # the demonstration's return from each of its rows, now known
                        rows_i = demo_rows.pop(i)
                        # a realised return cut by the time limit is no lower bound on Q (what the limit cut off is not
                        # in it): with training.demo_q_lower_bound such a demonstration's rows keep none
                        if term or not dc.demo_q_lower_bound:
                            replay.set_demo_return(rows_i, dc.gamma)
                    if curriculum is not None and not demo:      # the actor's failures, not the teacher's
                        curriculum.record(res.alpha_deg, cur_cfg.counts_success(res.success, r_succ))
                    elif curriculum is not None and demos is not None and demos.where_teacher_wins:
                        # the teacher's, apart, for training.demo_where_teacher_wins
                        curriculum.record_teacher(res.alpha_deg, cur_cfg.counts_success(res.success, r_succ))
                    _append_csv(out / "episodes.csv", EPISODE_FIELDS, {
                        "episode": slot_episode[i], "step": step, "return": f"{ep_ret[i]:.3f}",
                        "loaded": f"{res.loaded:.3f}", "outcome": info["outcome"] if term else "timeout",
                        "steps": res.steps, "alpha_deg": f"{res.alpha_deg:.2f}", "material": res.material,
                        "noise_scale": f"{scale:.4f}", "source": sources[i], "success": int(res.success),
                        "driver": f"scripted crowd {demo_crowd[i]:.3f}" if demo else "actor",
                        "r_success": f"{r_succ:.3f}"})
                    episode += 1
                    ep_ret[i] = 0.0
                    noises[i].reset()
                    slot_episode[i] = next_index()
                    obs[i] = reset_slot(i, episode_seed(seed, slot_episode[i], seed_offset))
                if step % dc.eval_every == 0 or step == dc.total_steps:
                    if replay.size >= dc.learning_starts:
                        closs = float((err * err).mean()) / dc.reward_scale ** 2
                        qmean = float(q.mean()) / dc.reward_scale
                    ev = evaluate(eval_env, agent.actor_numpy(), dc.eval_episodes, dc.eval_seed, bucket, breakdown=False)
                    row = {"step": step, "noise_scale": scale, "critic_loss": closs, "q_mean": qmean,
                           "episodes_done": episode, "wall_s": wall_before + time.perf_counter() - t0,
                           "eval_wall_s": ev["wall_s"], **{k: ev[k] for k in EVAL_FIELDS if k in ev and k != "wall_s"}}
                    _append_csv(out / "evals.csv", EVAL_FIELDS, {k: (f"{v:.6g}" if isinstance(v, float) else v)
                                                                 for k, v in row.items()})
                    if curriculum is not None:
                        edges = curriculum.edges
                        names = [f"p_{edges[k]:g}_{edges[k + 1]:g}" for k in range(len(edges) - 1)]
                        _append_csv(out / "curriculum.csv", ("step", *names),
                                    {"step": step, **{n: f"{v:.4f}" for n, v in zip(names, curriculum.probabilities())}})
                    if tb is not None:
                        for k in ("ar", "aml", "aff", "asl", "success_rate", "critic_loss", "q_mean"):
                            tb.add_scalar(f"eval/{k}", row[k], step)
                    last_eval = {k: row[k] for k in EVAL_FIELDS if k in row}
                    if dc.demo_bc > 0.0 and agent.bc_rows:
                        log(f"{variant} seed {seed}: step {step:,}: behaviour cloning on "
                            f"{agent.bc_passed / agent.bc_rows:.1%} of the {agent.bc_rows:,} demonstration rows sampled "
                            "since the last evaluation (the others failed the "
                            f"{'return filter' if replay.demo_return else 'Q-filter'})")
                        agent.bc_rows, agent.bc_passed = 0, 0
                    if dc.actor_preact_l2 > 0.0 and replay.size >= dc.learning_starts:
                        log(f"{variant} seed {seed}: step {step:,}: the actor's tanh input, mean ||z||^2 "
                            f"{agent.preact_sq:.3g} over the last batch (penalised at {dc.actor_preact_l2:g})")
                    if ramp.evaluated(ev["success_rate"], step):
                        log(f"{variant} seed {seed}: evaluation success {ev['success_rate']:.2f} at step {step:,}: the "
                            f"tilt penalty{' and the success margins are' if ramp.pitch_margin else ' is'} ramped in "
                            f"over {ramp.steps:,} steps")
                        write_run_json()
                    if best is None or _rank(last_eval) > _rank(best):
                        best = dict(last_eval)
                        export("best", best)
                    bar.eval_text = (f"eval@{step // 1000}k SR {ev['success_rate']:.2f} ASL {ev['asl']:.2f} "
                                     f"AML {ev['aml']:.1f} AR {ev['ar']:.0f}")
                    bar.update(step, force=True)
                if step % dc.checkpoint_every == 0 or step == dc.total_steps:
                    save_checkpoint()
                    write_run_json()
            bar.update(step)
    finally:
        bar.close()
        if tb is not None:
            tb.close()
        if pool is not None:
            pool.close()
    write_run_json()
    export("final", last_eval)
    return last_eval
