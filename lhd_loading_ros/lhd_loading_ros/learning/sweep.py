"""`lhd sweep STUDY.yaml [--address ADDR] [--jobs N]`: a training study on Ray core.

A study file (YAML) names the grid; every trial is one `lhd train` run, so a sweep writes the
same run folders as `lhd train --seeds` and `lhd report` / `lhd experiment` / `lhd ship` read them:

    out: runs/study_dr            # where the run folders go (relative to the study file's folder)
    variants: [rld, rlc]
    seeds: 0-4                    # as lhd train --seeds: '0-4', '0,2,5', or a list
    randomize: [false, true]      # domain randomisation presets (lhd train --randomize)
    steps: 300000                 # optional (default: training.total_steps of the config)
    config: ../config/lhd_params.yaml   # optional base parameter file
    overrides:                    # optional: parameter-file keys (section.key...); a list is a
      paper.ddpg.actor_lr: [1.0e-4, 3.0e-4]      # grid axis, a single value a fixed setting
      training.eval_episodes: 60

Run folders: <out>/<group>/seed_<N>, group = variant, "_dr" with randomisation, and
"_<key>=<value>" for each grid axis with several values (lhd report <out>/<group>). A trial
with overrides gets its own parameter file, <out>/configs/grid_<key>=<value>....yaml
(grid_fixed.yaml when no axis varies; its config hash is in the run's run.json, as for any run).
A value given twice (which would put two trials in one folder) is refused.

Each trial is a Ray task (num_cpus=1) that runs `lhd train ... --out <run folder>` as a child
process, its log in <out>/<group>/seed_<N>.log. Resumable: a trial whose final actor is what the
study would train now (config hash, variant, randomisation and steps in its policy.json) is skipped;
one trained under other settings (the study changed since) is refused by name, neither skipped nor
overwritten; the others resume from their checkpoint (lhd train's resume), so after
a crash (of a worker, a node or the driver) the same command goes on; Ray retries a task whose
worker died. Progress: one line per finished trial and <out>/sweep_status.json.

Ray: a local Ray (ray.init with --jobs CPUs, default all) unless --address names a running
cluster (`ray start --head` on one machine, `ray start --address HEAD:6379` on the others);
then the run folders must be on storage every node sees at the same path, and every node needs
this project installed (the same `make install`).
"""
from __future__ import annotations

import copy
import itertools
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from lhd_loading_ros.learning.runner import parse_seeds

KEYS = {"out", "variants", "seeds", "randomize", "steps", "config", "overrides"}
VARIANTS = ("rld", "rlc")


class StudyError(ValueError):
    pass


@dataclass
class Trial:
    group: str
    variant: str
    seed: int
    randomize: bool
    config_path: Path | None
    run_dir: Path
    steps: int | None
    settings: dict = field(default_factory=dict)
    cfg: dict | None = None          # the parameter file the trial trains under (validated), for stale()

    @property
    def name(self) -> str:
        return f"{self.group}/seed_{self.seed}"

    def command(self) -> list[str]:
        cmd = [sys.executable, "-m", "lhd_loading_ros.cli.main", "train", "--variant", self.variant,
               "--seed", str(self.seed), "--out", str(self.run_dir), "--no-progress"]
        if self.steps:
            cmd += ["--steps", str(self.steps)]
        if self.config_path:
            cmd += ["--config", str(self.config_path)]
        if self.randomize:
            cmd += ["--randomize"]
        return cmd

    def expected(self) -> dict:
        """What the trial's final actor records (policy.json) when trained under the study as it is now."""
        from lhd_loading_ros.task.config import config_hash

        cfg = self.cfg
        if self.randomize:             # as lhd train --randomize
            cfg = {**cfg, "randomization": {**cfg["randomization"], "enabled": 1}}
        return {"variant": self.variant, "config_hash": config_hash(cfg),
                "randomize": bool(int(cfg.get("randomization", {}).get("enabled", 0))),
                "steps": self.steps if self.steps is not None else int(cfg["training"]["total_steps"])}

    def stale(self) -> str | None:
        """Why the trial's final actor is not what the study would train now (another config hash, variant,
        randomisation, or more steps than the study's: the study's settings changed since), None when it
        is, when there is no final actor yet, or when it has fewer steps (the study with more steps
        resumes it: lhd train's resume)."""
        meta = self.run_dir / "final" / "policy.json"
        if not meta.is_file():
            return None
        try:
            m = json.loads(meta.read_text())
        except (ValueError, OSError) as exc:
            return f"final/policy.json unreadable ({exc})"
        want = self.expected() if self.cfg is not None else {"steps": self.steps} if self.steps is not None else {}
        tw = m.get("trained_with") if isinstance(m.get("trained_with"), dict) else {}
        got = {"variant": m.get("variant"), "config_hash": m.get("config_hash"), "randomize": tw.get("randomize"),
               "steps": m.get("steps")}
        if "randomize" not in tw:      # a card from before trained_with: its config hash says it
            want.pop("randomize", None)
        diff = [f"{k} {got[k]} != {v}" for k, v in want.items() if k != "steps" and got[k] != v]
        if "steps" in want and isinstance(got["steps"], int) and got["steps"] > want["steps"]:
            diff.append(f"steps {got['steps']} > {want['steps']}")
        return ", ".join(diff) or None

    def done(self) -> bool:
        """The final actor exists, is what the study would train now (stale() is None) and has the
        study's steps (fewer: resumed)."""
        meta = self.run_dir / "final" / "policy.json"
        if not meta.is_file() or self.stale() is not None:
            return False
        if self.steps is None and self.cfg is None:
            return True
        want = self.expected()["steps"] if self.cfg is not None else self.steps
        try:
            return int(json.loads(meta.read_text()).get("steps", -1)) == want
        except (ValueError, OSError):
            return False


def _set_key(cfg: dict, dotted: str, value) -> None:
    node = cfg
    parts = dotted.split(".")
    for p in parts[:-1]:
        if not isinstance(node, dict) or p not in node:
            raise StudyError(f"override {dotted!r}: the parameter file has no section {p!r}; expected a key such as "
                             "paper.ddpg.actor_lr or training.eval_episodes")
        node = node[p]
    if not isinstance(node, dict) or parts[-1] not in node:
        raise StudyError(f"override {dotted!r}: the parameter file has no key {parts[-1]!r} there")
    node[parts[-1]] = value


def _tag(value) -> str:
    text = repr(value) if isinstance(value, float) else str(value)     # repr: two values never print alike
    return "".join(c if (c.isalnum() or c in ".-+") else "-" for c in text)


def load_study(path) -> tuple[Path, list[Trial]]:
    """The study's output folder and its trials; StudyError naming what is wrong."""
    from lhd_loading_ros.task.config import ConfigError, load_config

    path = Path(path)
    try:
        study = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise StudyError(f"cannot read study file {path}: {exc}") from None
    except yaml.YAMLError as exc:
        raise StudyError(f"{path} is not valid YAML: {exc}") from None
    if not isinstance(study, dict):
        raise StudyError(f"{path}: expected a mapping with keys {sorted(KEYS)}")
    unknown = set(study) - KEYS
    if unknown:
        raise StudyError(f"{path}: unknown keys {sorted(unknown)}; expected {sorted(KEYS)}")
    base = path.parent
    if "out" not in study:
        raise StudyError(f"{path}: 'out' (the folder of the run folders) is required")
    out = (base / str(study["out"])).resolve()
    variants = study.get("variants", ["rld"])
    variants = [variants] if isinstance(variants, str) else list(variants)
    if not variants or any(v not in VARIANTS for v in variants):
        raise StudyError(f"{path}: variants {variants}; expected a list of {VARIANTS}")
    seeds = study.get("seeds", [0])
    try:
        seeds = parse_seeds(str(seeds)) if isinstance(seeds, (str, int)) else parse_seeds(",".join(map(str, seeds)))
    except ValueError as exc:
        raise StudyError(f"{path}: {exc}") from None
    rand = study.get("randomize", [False])
    rand = [rand] if isinstance(rand, bool) else (list(rand) if isinstance(rand, list) else [rand])
    if not rand or any(not isinstance(r, bool) for r in rand):
        raise StudyError(f"{path}: randomize {rand}; expected true, false or a list of them")
    steps = study.get("steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise StudyError(f"{path}: steps {steps!r}; expected a positive integer")
    cfg_path = (base / str(study["config"])).resolve() if study.get("config") else None
    try:
        base_cfg = load_config(cfg_path)
    except ConfigError as exc:
        raise StudyError(f"{path}: {exc}") from None
    overrides = study.get("overrides") or {}
    if not isinstance(overrides, dict):
        raise StudyError(f"{path}: overrides must map parameter keys to a value or a list of values")
    axes = {k: (list(v) if isinstance(v, list) else [v]) for k, v in overrides.items()}
    for k, vals in axes.items():
        if not vals:
            raise StudyError(f"{path}: override {k!r} has an empty list of values")
    varying = [k for k, vals in axes.items() if len(vals) > 1]
    trials = []
    for combo in itertools.product(*axes.values()) if axes else [()]:
        settings = dict(zip(axes, combo))
        cfg_file = cfg_path
        suffix = "".join(f"_{k.split('.')[-1]}={_tag(settings[k])}" for k in varying)
        if settings:
            cfg = copy.deepcopy(base_cfg)
            for k, v in settings.items():
                _set_key(cfg, k, v)
            cfg_file = out / "configs" / f"grid{suffix or '_fixed'}.yaml"
            from lhd_loading_ros.task.config import validate

            try:
                checked = validate(copy.deepcopy(cfg))      # as lhd train will read the file written from cfg
            except ConfigError as exc:
                raise StudyError(f"{path}: overrides {settings} make an invalid parameter file: {exc}") from None
            settings["_config"] = cfg
        else:
            checked = base_cfg
        for variant, r in itertools.product(variants, rand):
            group = f"{variant}{'_dr' if r else ''}{suffix}"
            for s in seeds:
                trials.append(Trial(group, variant, s, r, cfg_file, out / group / f"seed_{s}", steps, settings,
                                    checked))
    seen: dict = {}
    for t in trials:
        seen.setdefault(t.run_dir, []).append(t)
    clash = {d: ts for d, ts in seen.items() if len(ts) > 1}
    if clash:
        d, ts = next(iter(clash.items()))
        raise StudyError(f"{path}: {len(clash)} run folder(s) would hold several trials, e.g. {d.relative_to(out)} for "
                         f"{len(ts)} trials: a variant, a randomize value or an override value given twice; expected "
                         "each value once")
    return out, trials


def _write_configs(trials: list[Trial]) -> None:
    for t in trials:
        cfg = t.settings.get("_config")
        if cfg is not None and t.config_path is not None:
            t.config_path.parent.mkdir(parents=True, exist_ok=True)
            t.config_path.write_text(yaml.safe_dump(cfg, sort_keys=False))


def _last_line(path: Path) -> str:
    try:
        lines = [ln for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return "no log"
    return lines[-1][-300:] if lines else "empty log"


def run_trial(cmd: list[str], log_path: str) -> dict:
    """The body of one Ray task: `lhd train` as a child process (it resumes from its checkpoint)."""
    t0 = time.time()
    with open(log_path, "ab") as log:
        rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    return {"exit": rc, "wall_s": time.time() - t0, "host": os.uname().nodename}


def check_address(address: str, timeout: float = 5.0) -> None:
    """A cluster address (HOST:PORT or ray://HOST:PORT) must accept a TCP connection before Ray is
    asked to join it: ray.init retries an unreachable one for minutes. ConnectionError saying
    what to do; 'auto' (Ray finds a local cluster) is left to Ray."""
    import socket

    if address == "auto":
        return
    rest = address.split("://", 1)[-1]
    host, sep, port = rest.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise StudyError(f"--address {address!r}: expected HOST:PORT (the head node's GCS port, e.g. 10.0.0.5:6379), "
                         "ray://HOST:PORT or auto")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout):
            pass
    except OSError as exc:
        raise ConnectionError(f"{exc.strerror or exc}; start the cluster's head with `ray start --head` (port 6379 by "
                              "default) or give its address") from None


def sweep(study_path, address: str | None = None, jobs: int | None = None, log=print) -> int:
    out, trials = load_study(study_path)
    stale = [(t, why) for t in trials if (why := t.stale()) is not None]
    if stale:       # neither skipped as done nor overwritten: the user decides (a review, 2026-11-30)
        raise StudyError(
            f"{len(stale)} finished trial(s) were trained under other settings than the study's now (the study "
            "file, its overrides or its config changed since): "
            + "; ".join(f"{t.name} ({why})" for t, why in stale[:5]) + (" ..." if len(stale) > 5 else "")
            + f"; move those run folders out of {out} to train them again under the new settings, or give the "
            "study another 'out'")
    out.mkdir(parents=True, exist_ok=True)
    todo = [t for t in trials if not t.done()]
    status = {"study": str(Path(study_path).resolve()), "out": str(out), "trials": len(trials),
              "skipped_done": len(trials) - len(todo), "finished": [], "failed": [], "running": [t.name for t in todo]}
    status_path = out / "sweep_status.json"

    def save():
        tmp = status_path.with_suffix(".tmp")
        tmp.write_text(json.dumps(status, indent=2) + "\n")
        os.replace(tmp, status_path)

    log(f"lhd sweep: {len(trials)} trials in {out}; {len(trials) - len(todo)} already done, {len(todo)} to run")
    if not todo:
        save()
        return 0
    _write_configs(todo)
    for t in todo:
        t.run_dir.parent.mkdir(parents=True, exist_ok=True)

    import ray

    t0 = time.time()
    kw = {"include_dashboard": False, "log_to_driver": False, "configure_logging": False}
    if address:
        check_address(address)
        ray.init(address=address, **kw)
    else:
        ray.init(num_cpus=jobs or os.cpu_count() or 1, object_store_memory=100 * 1024 * 1024, **kw)
    import signal

    def on_term(*_):                 # SIGTERM as Ctrl-C: the same orderly stop (Ray's handler dumps a stack)
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        task = ray.remote(num_cpus=1, max_retries=2)(run_trial)
        pending = {task.remote(t.command(), str(t.run_dir.parent / f"seed_{t.seed}.log")): t for t in todo}
        save()
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=10.0)
            for ref in ready:
                t = pending.pop(ref)
                try:
                    res = ray.get(ref)
                except Exception as exc:           # the task failed beyond its retries
                    res = {"exit": -1, "wall_s": float("nan"), "host": "?", "error": str(exc).splitlines()[0]}
                status["running"].remove(t.name)
                entry = {"trial": t.name, **res}
                ok = res["exit"] == 0 and t.done()
                if not ok:
                    entry["reason"] = res.get("error") or _last_line(t.run_dir.parent / f"seed_{t.seed}.log")
                (status["finished"] if ok else status["failed"]).append(entry)
                n = len(status["finished"]) + len(status["failed"])
                log(f"[{n}/{len(todo)}] {t.name}: {'done' if ok else 'FAILED (exit %s): %s' % (res['exit'], entry['reason'])}"
                    f" in {res['wall_s']:.0f} s on {res['host']} ({time.time() - t0:.0f} s since the start)")
                save()
    except KeyboardInterrupt:
        log("interrupted; run the same command again to resume (finished trials are skipped, the others "
            "resume from their checkpoints)")
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)
        ray.shutdown()
    status["wall_s"] = time.time() - t0
    save()
    if status["failed"]:
        log(f"lhd sweep: {len(status['failed'])} trial(s) failed: "
            + ", ".join(f"{e['trial']} (log {out / e['trial']}.log)" for e in status["failed"]))
        return 1
    groups = sorted({t.group for t in trials})
    log(f"lhd sweep: all {len(trials)} trials done in {status['wall_s']:.0f} s; figures: lhd report "
        + " ".join(str(out / g) for g in groups))
    return 0
