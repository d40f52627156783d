"""`lhd ship --variant V RUNS_DIR`: pick the shipped actor of a variant from its seeds, evaluate
it on the held-out seed and write the model card (policies/<variant>/README.md + curves).

Selection (`select`):
- "median" (default): each seed's `final/` actor (the end of training, no checkpoint picking) is
  evaluated on the held-out evaluation seed and the seeds are ranked by (success rate, ASL, AR);
  the median seed ships (the lower of the two middle ones for an even count). A user who retrains
  with another seed gets an actor like it, not like the luckiest run.
- "best": each seed's `best/` actor (its best training-time evaluation) is evaluated held-out and
  the highest ranked ships; the card then says that it is the best of the seeds, not a typical one.
- "best-final": each seed's `final/` actor (no checkpoint picking), the highest ranked ships; as
  the held-out seed chose it, its own table is evaluated again on piles that took no part in the
  choice (CONFIRM_SEED), and the card shows the seeds' distribution as what a retraining user gets.

`max_tilt_rate` (`--max-tilt-rate`; default None, no gate): a seed whose actor lifts the machine's
rear over 5 deg in more than this share of its held-out attempts (a breakout that pries the machine,
docs/modeling.md "The machine's own tilt") is left out of the selection; the card lists it and why.
The median is then the median of the seeds that remain."""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from lhd_loading_ros.task import json_out
from lhd_loading_ros.task.config import load_config, trained_randomized
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.learning.evaluate import EVAL_SLOPES, evaluate, evaluate_under
from lhd_loading_ros.learning.report import plot_curves, summarize

HELD_OUT_SEED = 2_000_000
CONFIRM_SEED = 3_000_000     # best-final: the shipped actor's figures on piles the selection never saw


def _brief(ev: dict) -> dict:
    out = {k: ev[k] for k in ("episodes", "success_rate", "asl", "aml", "ar", "elapsed_s", "front_drift_pct",
                              "rear_drift_pct")}
    out["restricted_zone"], out["timeout"] = ev["failures"]["restricted_zone"], ev["failures"]["timeout"]
    out["refused"] = ev.get("refused", 0)     # told a slope outside the trained range: not run (task.metrics.aggregate)
    return out


def _table(ev: dict) -> str:
    head = ("| | episodes | success | ASL | AML [kg] | AFF | AR | elapsed [s] | front drift % | rear drift % | end zone "
            "| tilt [deg] | tilt > 5 deg |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|")

    def row(name, r):
        return (f"| {name} | {r['episodes']} | {r['success_rate']:.3f} | {r['asl']:.2f} | {r['aml']:.1f} | "
                f"{r['aff']:.2f} | {r['ar']:.0f} | {r['elapsed_s']:.2f} | {r['front_drift_pct']:.1f} | "
                f"{r['rear_drift_pct']:.1f} | {r['end_zone_rate']:.2f} | {r.get('max_tilt_deg', float('nan')):.2f} | "
                f"{r.get('tilt_over_5deg_rate', float('nan')):.2f} |")
    lines = [head, row("all", ev)]
    lines += [row(f"{k} deg", v) for k, v in ev["by_slope"].items()]
    lines += [row(k, v) for k, v in ev["by_material"].items()]
    return "\n".join(lines)


SELECTIONS = ("median", "best", "best-final")


def gate_tilt(cands: list, max_tilt_rate: float | None) -> tuple[list, list]:
    """(kept, left out): candidates (key, dir, policy, evaluation) whose held-out share of attempts
    tilting the machine over 5 deg is at most max_tilt_rate (all of them when it is None)."""
    if max_tilt_rate is None:
        return list(cands), []
    if not (0.0 <= max_tilt_rate <= 1.0):
        raise ValueError(f"max_tilt_rate = {max_tilt_rate!r}: expected a share in [0, 1]")
    kept = [c for c in cands if c[3].get("tilt_over_5deg_rate", 0.0) <= max_tilt_rate]
    if cands and not kept:
        raise ValueError(f"every seed lifts the machine's rear over 5 deg in more than {max_tilt_rate:g} of its "
                         "held-out attempts (" + ", ".join(f"{c[1].name} {c[3].get('tilt_over_5deg_rate', 0.0):.2f}"
                                                           for c in cands) + "): nothing to ship under this gate")
    return kept, [c for c in cands if c not in kept]


def pick(ranked: list, select: str):
    """ranked: (key, ...) tuples. "median": the median by key (the lower middle one for an
    even count); "best" / "best-final": the highest key."""
    if select not in SELECTIONS:
        raise ValueError(f"select must be one of {SELECTIONS}, got {select!r}")
    order = sorted(ranked, key=lambda c: c[0])
    return order[-1] if select in ("best", "best-final") else order[(len(order) - 1) // 2]


def ramp_progress(run_dir: Path, meta: dict) -> tuple[int | None, float | None]:
    """The tilt penalty's ramp for an exported actor: (the step it began, None if it never did;
    the weight at the actor's step, None when nothing recorded it). From the card (exports since
    the ramp's weight is written) or the run's run.json."""
    tr = meta.get("tilt_ramp")
    if isinstance(tr, dict) and "weight" in tr:
        return tr.get("start_step"), float(tr["weight"])
    try:
        tr = json.loads((Path(run_dir) / "run.json").read_text()).get("tilt_ramp")
    except (OSError, ValueError):
        return None, None
    if not isinstance(tr, dict):
        return None, None
    start, steps = tr.get("start_step"), int(tr.get("steps", 0))
    if start is None:
        return None, 0.0
    at = int(meta.get("steps", 0))
    return int(start), (1.0 if steps == 0 else min(1.0, max(0.0, (at - int(start)) / steps)))


PARAMS_FILE = "lhd_params.yaml"
HEADER_PREFIX = "#| "     # the lines lhd ship puts above a copied parameter file (dropped when re-shipped)


def shown_path(out: Path) -> str:
    """`out` as the card shows it: relative to the working directory when inside it (a card that
    travels with the repository must not name one machine's folders), else as given."""
    try:
        return out.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return out.as_posix()


def parameter_file_need(pol, cfg: dict) -> str:
    """What the shipped actor needs of its parameter file: "own" when the project's default file
    (config/lhd_params.yaml of the source tree or the installed package, not $LHD_CONFIG) scales its
    observation otherwise, so it runs only with `cfg`; "evaluated" when it would run under the
    default but `cfg` differs from it elsewhere (its card's figures come from `cfg`); "" when `cfg`
    is the default's."""
    from lhd_loading_ros.policy.shipped import shipped_config
    from lhd_loading_ros.task.config import config_hash

    default = load_config(str(shipped_config("lhd_params.yaml")))
    if pol.observation_mismatch(default) is not None or pol.action_mismatch(default) is not None:
        return "own"
    return "evaluated" if config_hash(default) != config_hash(cfg) else ""


def write_parameter_file(text: str, src: str, out: Path, shown: str, need: str) -> None:
    """Write `text` (the parameter file the actor was shipped with, read before `out` was
    replaced) as `out`/lhd_params.yaml, under a header saying why it is there and how to pass it."""
    body = "".join(ln for ln in text.splitlines(keepends=True) if not ln.startswith(HEADER_PREFIX))
    why = ("the default config/lhd_params.yaml scales its observation otherwise: it runs only with this file"
           if need == "own" else "the figures of its card were computed under this file (the default scales its "
           "observation the same way)")
    header = (f"{HEADER_PREFIX}The parameter file of the actor in {shown} (a copy of {src}, written by lhd ship):\n"
              f"{HEADER_PREFIX}{why}.\n"
              f"{HEADER_PREFIX}Pass it with --config {shown}/{PARAMS_FILE} (lhd) or -p config:={shown}/{PARAMS_FILE} (the nodes).\n")
    (out / PARAMS_FILE).write_text(header + body)


def _recipe_note(tw: dict) -> str:
    """The training settings beyond the paper's DDPG that the card names (trained_with)."""
    parts = []
    demo = tw.get("demonstrations") if isinstance(tw.get("demonstrations"), dict) else {}
    share = float(demo.get("demo_share", 0.0) or 0.0)
    if share > 0:
        until = int(tw.get("demo_until_step", 0) or 0)
        parts.append(f"scripted demonstrations in {share:.0%} of the training episodes "
                     + (f"until step {until:,}" if until > 0 else "until the exploration noise's decay ends")
                     + ((" with behaviour cloning on them where the demonstration's own return beat the critic's "
                         f"value of the actor (weight {float(tw['demo_bc']):g})" if tw.get("demo_bc_filter") == "return"
                         else f" with Q-filtered behaviour cloning on them (weight {float(tw['demo_bc']):g})")
                        if float(tw.get("demo_bc", 0.0) or 0.0) > 0 else ""))
        if int(tw.get("demo_told_zones", 0) or 0):
            stop = float(tw.get("demo_end_zone_stop", 0.0) or 0.0)
            parts.append("the demonstrations reading the zones built from the told slope, as the actor does"
                         + (f", and stopping their wheels while they lift below the end zone within {stop:g} m of its "
                            "far side" if stop > 0 else ""))
        push_curl, late = float(tw.get("demo_push_curl", 0.0) or 0.0), float(tw.get("demo_late_lift", 0.0) or 0.0)
        if push_curl > 0 or late > 0:
            what = [f"pushing with the bucket curled to {push_curl:g} rad"] if push_curl > 0 else []
            what += [f"lifting, unstalled, at {late:g} of the end zone's length"] if late > 0 else []
            parts.append("the demonstrations " + " and ".join(what))
        told_high = float(tw.get("demo_told_high", 0.0) or 0.0)
        if told_high > 0:
            parts.append(f"every episode told the slope {told_high:g} deg or more too steep a demonstration")
        failing = float(tw.get("demo_failing_share", 0.0) or 0.0)
        if failing > 0:
            parts.append(f"an episode on a slope bin the actor still fails a demonstration with probability {failing:g} "
                         "x the bin's failure rate")
        if int(tw.get("demo_where_teacher_wins", 0) or 0):
            parts.append("demonstrations only on the slope bins where the teacher's recent success rate is at least "
                         "the actor's")
        confirm = int(tw.get("demo_drift_confirm", 1) or 1)
        if confirm > 1:
            parts.append(f"the demonstrations reading the drift flags the actor sees and lifting on one only after "
                         f"{confirm} steps in a row")
    if int(tw.get("reward_zones_from_pile", 0) or 0):
        parts.append("the reward's terms reading the pile's own zones where the slope was told wrong "
                     "(`task.reward_zones_from_pile`; the observation and the episode's end the told ones)")
    if int(tw.get("midgoal_from_pile", 0) or 0):
        parts.append("the mid goal x_midgoal at the start of the pile's end zone (`task.midgoal_from_pile`, a "
                     "departure from the paper's reward)")
    if int(tw.get("twin_critics", 0) or 0):
        parts.append("clipped double Q (two critics, the smaller target; Fujimoto et al. 2018)")
    if float(tw.get("critic_huber", 0.0) or 0.0) > 0:
        parts.append(f"a Huber critic loss (delta {float(tw['critic_huber']):g})")
    if float(tw.get("actor_preact_l2", 0.0) or 0.0) > 0:
        parts.append(f"a penalty on the actor's tanh input (weight {float(tw['actor_preact_l2']):g}), so that its outputs "
                     "do not saturate")
    if int(tw.get("demo_q_lower_bound", 0) or 0):
        parts.append("the demonstrations' own returns as a lower bound on the critics' target")
    if float(tw.get("noise_after_decay", 0.0) or 0.0) > 0:
        parts.append(f"exploration noise {float(tw['noise_after_decay']):g} after its decay")
    if tw.get("lr_final_scale") is not None and float(tw["lr_final_scale"]) != 1.0:
        parts.append(f"learning rates falling to {float(tw['lr_final_scale']):g} of their start")
    if isinstance(tw.get("slope_curriculum"), dict) and int(tw["slope_curriculum"].get("bins", 0) or 0) > 0:
        parts.append("a slope curriculum" + (" counting the reward's success (r_success paid), not the paper's test"
                                              if int(tw["slope_curriculum"].get("reward_test", 0) or 0) else ""))
    return "".join(f", {p}" for p in parts)


def drawn_conditions(cfg: dict) -> str:
    """What `lhd eval --randomize` draws under this parameter file's `randomization` section, in words (the
    card's "When the machine differs"): the ranges of the file, not of the file the card was first written for."""
    r = cfg["randomization"]
    zones = (" (the zones built from it move too)" if int(r.get("zones_from_slope_estimate", 0))
             else " (in the observed slope only)")
    parts = [f"slope-estimate error up to +-{r['slope_error_max_deg']:g} deg{zones}", "camera noise, dropouts and delay",
             f"0-{1000.0 * r['actuator_delay_max_s']:.0f} ms actuator dead time",
             f"gravel of {r['density_min']:,.0f}-{r['density_max']:,.0f} kg/m^3, friction angle "
             f"{r['phi_min_deg']:g}-{r['phi_max_deg']:g} deg, cohesion up to {r['cohesion_max']:,.0f} Pa and up to "
             f"{int(r['rocks_max'])} rocks",
             f"tyre friction {r['tyre_friction_min']:g}-{r['tyre_friction_max']:g}",
             f"start pose (heading +-{r['heading_max_deg']:g} deg, lip +-{100.0 * r['lateral_offset_max']:g} cm)"]
    drive = (float(r.get("drive_gain_min", 1.0)), float(r.get("drive_gain_max", 1.0)))
    hyd = (float(r.get("hydraulic_gain_min", 1.0)), float(r.get("hydraulic_gain_max", 1.0)))
    if drive != (1.0, 1.0):
        parts.append(f"wheels at {drive[0]:g}-{drive[1]:g} of their commanded speed")
    if hyd != (1.0, 1.0):
        parts.append(f"boom and bucket at {hyd[0]:g}-{hyd[1]:g} of their commanded rates")
    if float(r.get("rest_start_share", 0.0)) > 0.0:
        parts.append(f"{100.0 * float(r['rest_start_share']):g} % of the attempts from rest with the tip in the pile")
    if float(r.get("surface_sd_max", 0.0)) > 0.0:
        parts.append(f"a rough face (relief sd up to {100.0 * float(r['surface_sd_max']):g} cm)")
    if float(r.get("arm_offset_max_deg", 0.0)) > 0.0:
        parts.append(f"boom and bucket angle sensors up to +-{float(r['arm_offset_max_deg']):g} deg off their zero")
    if float(r.get("slope_error_high_share", 0.0)) > 0.0:
        parts.append(f"the slope error of {100.0 * float(r['slope_error_high_share']):g} % of the attempts drawn "
                     f"{0.5 * float(r['slope_error_max_deg']):g}-{float(r['slope_error_max_deg']):g} deg too steep "
                     "(the others' from the whole range)")
    if float(r.get("slope_error_small_share", 0.0)) > 0.0:
        parts.append(f"the slope error of {100.0 * float(r['slope_error_small_share']):g} % of the attempts within "
                     f"+-{float(r['slope_error_small_max_deg']):g} deg (the LiDAR right; the others' from the whole range)")
    if float(r.get("drift_flag_lag_max_s", 0.0)) > 0.0:
        parts.append(f"the drift flag over a control period ending up to {1000.0 * float(r['drift_flag_lag_max_s']):.0f} ms "
                     "before the observation (the bridge's window)")
    return ", ".join(parts)


def check_out(out, runs_dir, runs=()) -> None:
    """Refuse an --out whose replacement would destroy what it must not (a review, 2026-11-30: `lhd ship RUNS
    --out RUNS` deleted every seed's checkpoints): `out` must not be, contain or lie inside `runs_dir` or one of
    `runs` (the seeds' folders), and a folder already there must be a policy folder (policy.json), which
    is replaced; an empty folder is used as well. ValueError naming what was wrong."""
    o = Path(out).resolve()
    for d in [Path(runs_dir), *map(Path, runs)]:
        r = d.resolve()
        if o == r or r.is_relative_to(o):
            raise ValueError(f"--out {out} {'is' if o == r else 'contains'} the training runs {d}: shipping replaces "
                             "--out and would delete them; expected a policy folder outside the runs, e.g. "
                             "policies/<variant>")
        if o.is_relative_to(r):
            raise ValueError(f"--out {out} lies inside the training runs {d}; expected a policy folder outside "
                             "them, e.g. policies/<variant>")
    p = Path(out)
    if p.exists() or p.is_symlink():
        if not p.is_dir():
            raise ValueError(f"--out {out} exists and is not a folder; expected a new folder or a policy folder "
                             "(one with policy.json) to replace")
        if not (p / "policy.json").is_file() and any(p.iterdir()):
            raise ValueError(f"--out {out} exists and is not a policy folder (no policy.json): lhd ship replaces "
                             "its --out and would delete what is there; expected a new folder or a policy folder "
                             "written by lhd ship")


def check_alike(runs: list, metas: list, sub: str, final_steps: list) -> None:
    """Refuse seeds that are not alike: actors with different config hashes (trained on other parameter
    files), or runs trained for different numbers of steps (`sub` final: their final actors' steps; else
    the runs' last evaluations, `final_steps`): their ranking would mix training stages."""
    hashes = {m.get("config_hash") for m in metas}
    if len(hashes) > 1:
        raise ValueError(f"the seeds' {sub}/ actors were trained on different parameter files (config hash "
                         + ", ".join(f"{d.name} {m.get('config_hash')}" for d, m in zip(runs, metas))
                         + "); expected one study's seeds: ship from a folder holding only runs of one config")
    steps = [int(m.get("steps", -1)) for m in metas] if sub == "final" else [int(s) for s in final_steps]
    if len(set(steps)) > 1:
        raise ValueError("the seeds were trained for different numbers of steps ("
                         + ", ".join(f"{d.name} {s:,}" for d, s in zip(runs, steps))
                         + "): their ranking would mix training stages; resume the shorter ones with the same "
                         "lhd train command and the larger --steps, or ship from a folder holding runs of one length")


def _install(tmp: Path, out: Path) -> None:
    """Put the finished folder `tmp` (a sibling of `out`) in the place of `out`: the old one is renamed aside
    first and removed only once the new one is in place."""
    old = None
    if out.exists() or out.is_symlink():
        old = out.with_name(f".{out.name}.old-{os.getpid()}")
        os.replace(out, old)
    os.replace(tmp, out)
    if old is not None:
        if old.is_symlink() or not old.is_dir():
            old.unlink()
        else:
            shutil.rmtree(old)


def ship(variant: str, runs_dir, out, episodes: int = 120, config=None, log=print, select: str = "median",
         max_tilt_rate: float | None = None) -> dict:
    from lhd_sim_node.env import LhdLoadingEnv

    if select not in SELECTIONS:
        raise ValueError(f"select must be one of {SELECTIONS}, got {select!r}")
    gate_tilt([], max_tilt_rate)          # a bad gate is refused before the seeds are evaluated
    sub = "best" if select == "best" else "final"
    cfg = load_config(config)
    runs = sorted(d for d in Path(runs_dir).glob("seed_*") if (d / sub / "policy.json").is_file())
    if not runs:
        raise FileNotFoundError(f"{runs_dir} holds no finished seed (seed_*/{sub}/policy.json)")
    unfinished = sorted(d.name for d in Path(runs_dir).glob("seed_*") if d.is_dir() and d not in runs)
    out = Path(out)
    check_out(out, runs_dir, runs)       # before any evaluation: a wrong --out costs nothing
    summary = summarize(runs)
    check_alike(runs, [json.loads((d / sub / "policy.json").read_text()) for d in runs], sub, summary["final_steps"])
    if unfinished:      # named, not dropped in silence (a review, 2026-11-29): the median is of the others
        log(f"left out, no {sub}/ actor (training unfinished: resume it with the same lhd train command): "
            f"{', '.join(unfinished)}")
    # the pile's own zones, as evaluate_under's default and the card's `lhd eval` command (--zones pile)
    env = LhdLoadingEnv(variant, cfg, zones_from_estimate=True, zones_nominal_density=False)
    # RLC is ranked as the policy node runs it, with the deployment filter (as `lhd report` evaluates
    # it): the raw actor and the filtered one can rank the seeds differently
    env_deploy = (LhdLoadingEnv(variant, cfg, deploy_filter=True, zones_from_estimate=True, zones_nominal_density=False)
                  if variant == "rlc" else None)
    cands = []
    for d in runs:
        pol = load_policy(d / sub).check_config(cfg)
        if pol.variant != variant:
            raise ValueError(f"{d}/{sub} is a {pol.variant} actor, not {variant}")
        ev = evaluate(env, pol.actor, episodes, HELD_OUT_SEED, cfg["task"]["bucket_capacity"])
        rank_ev, note = ev, ""
        if env_deploy is not None:
            evd = evaluate(env_deploy, pol.actor, episodes, HELD_OUT_SEED, cfg["task"]["bucket_capacity"])
            ev["with_deployment_filter"] = {k: evd[k] for k in ("success_rate", "asl", "aml", "ar", "elapsed_s")}
            rank_ev, note = evd, f"; with the deployment filter {evd['success_rate']:.3f}, ASL {evd['asl']:.2f}"
        log(f"{d.name}/{sub}: held-out success {ev['success_rate']:.3f}, ASL {ev['asl']:.2f}, AML {ev['aml']:.1f}{note}")
        cands.append(((rank_ev["success_rate"], rank_ev["asl"], rank_ev["ar"]), d, pol, ev))
    kept, gated = gate_tilt(cands, max_tilt_rate)
    for c in gated:
        log(f"{c[1].name}/{sub} left out: it lifts the machine's rear over 5 deg in "
            f"{c[3]['tilt_over_5deg_rate']:.0%} of its held-out attempts (--max-tilt-rate {max_tilt_rate:g})")
    _, best_dir, pol, ev = pick(kept, select)
    log(f"shipping {best_dir.name}/{sub} ({'median' if select == 'median' else 'best'} of {len(kept)} seeds"
        f"{f', {len(gated)} left out for tilting the machine' if gated else ''})")
    start, weight = ramp_progress(best_dir, pol.meta)
    if weight is not None and weight < 1.0:
        log(f"warning: {best_dir.name}/{sub} has {weight:.0%} of the tilt penalty (its ramp "
            f"{'never began' if start is None else f'began at step {start:,}'}): the card says so")
    eval_seed = HELD_OUT_SEED
    if select == "best-final":   # the selection's own piles flatter the winner: evaluate it on others
        eval_seed = CONFIRM_SEED
        ev = evaluate(env, pol.actor, episodes, eval_seed, cfg["task"]["bucket_capacity"])
        log(f"{best_dir.name}/{sub} on the confirmation seed {eval_seed:,}: success {ev['success_rate']:.3f}, "
            f"ASL {ev['asl']:.2f}, AML {ev['aml']:.1f}")
    config_text = Path(config).read_text() if config is not None else None   # before `out` goes: it may hold it
    check_out(out, runs_dir, runs)       # again: nothing may have appeared there meanwhile
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")     # written in full here, then renamed into place
    if tmp.exists():
        shutil.rmtree(tmp)
    shutil.copytree(best_dir / sub, tmp)
    try:
        res = _write_card(variant, runs, tmp, out, config, config_text, cfg, pol, ev, env_deploy, episodes, eval_seed,
                          select, sub, best_dir, cands, kept, gated, unfinished, max_tilt_rate, summary, log)
        _install(tmp, out)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return res


def _write_card(variant, runs, tmp: Path, out: Path, config, config_text, cfg, pol, ev, env_deploy, episodes,
                eval_seed, select, sub, best_dir, cands, kept, gated, unfinished, max_tilt_rate, summary, log) -> dict:
    """The card, evaluation.json, curves and parameter file of the shipped actor, written into `tmp`
    (renamed to `out` by the caller); the card names `out`."""
    plot_curves({variant.upper(): runs}, tmp / "training_curves.png")
    shown = shown_path(out)
    need = parameter_file_need(pol, cfg) if config is not None else ""
    own_params = bool(need)
    if own_params:
        src = shown_path(Path(config))
        write_parameter_file(config_text, src, tmp, shown, need)
        log(f"copied {src} to {shown}/{PARAMS_FILE}: "
            + ("the actor runs only with it" if need == "own" else "the card's figures were computed under it"))
    run_cfg = f" --config {shown}/{PARAMS_FILE}" if own_params else ""
    node_cfg = f" -p config:={shown}/{PARAMS_FILE}" if own_params else ""
    deploy_note = ""
    if variant == "rlc":   # as the policy node runs it: with the deployment filter
        if "with_deployment_filter" in ev:        # the ranking's evaluation, on these piles already
            evd = ev["with_deployment_filter"]
        else:                                     # best-final: on the confirmation seed
            evd = evaluate(env_deploy, pol.actor, episodes, eval_seed, cfg["task"]["bucket_capacity"])
            ev["with_deployment_filter"] = {k: evd[k] for k in ("success_rate", "asl", "aml", "ar", "elapsed_s")}
        deploy_note = (f"\nWith the deployment filter, as the policy node and the machine run it (`lhd eval --policy "
                       f"{shown}{run_cfg} --deploy-filter --seed {eval_seed}`): success {evd['success_rate']:.3f}, ASL {evd['asl']:.2f}, "
                       f"AML {evd['aml']:.1f} kg, {evd['elapsed_s']:.2f} s.\n")
    # what the machine will do differently (docs/training.md "Domain randomisation"): the same
    # held-out piles under drawn conditions and at the placement corners, as the policy node runs it
    deploy = variant == "rlc"
    ev["randomized"] = _brief(evaluate_under("randomized", variant, pol.actor, cfg, episodes, eval_seed))
    ev["stress_placement"] = _brief(evaluate_under("placement", variant, pol.actor, cfg, episodes, eval_seed))
    ev["evaluation_seed"] = eval_seed
    (tmp / "evaluation.json").write_text(json_out.dumps(ev, indent=1) + "\n")
    m = pol.meta
    lo_deg, hi_deg, _ = pol.trained_slope_range_deg(cfg)
    own_note = {"own": (" Under a parameter file that scales the observation otherwise (the default "
                        "config/lhd_params.yaml among them) `lhd` refuses it and names what differs; the policy node "
                        "commands zero and says why on /diagnostics (docs/ros_nodes.md)."),
                "evaluated": (" The default config/lhd_params.yaml scales the observation the same way, so the actor "
                              "also runs under it, but the figures below were computed under this file."),
                "": ""}[need]
    ep_cfg = cfg["paper"]["episode"]
    cfg_range = (float(ep_cfg["alpha_min_deg"]), float(ep_cfg["alpha_max_deg"]))
    held_slopes = ", ".join(f"{x:g}" for x in EVAL_SLOPES)
    other_piles = (f" (`lhd experiment paper --slopes` runs it on others of {cfg_range[0]:g}-{cfg_range[1]:g} deg)"
                   if cfg_range != (min(EVAL_SLOPES), max(EVAL_SLOPES)) else "")
    tw = m.get("trained_with")
    trained_dr = (bool(tw.get("randomize")) if isinstance(tw, dict)       # cards from before trained_with:
                  else trained_randomized(m.get("config_hash"), cfg))     # by their hash
    dr_note = ("Trained with domain randomisation (`lhd train --randomize`, the config's `randomization` section)."
               if trained_dr else "Trained without domain randomisation.")
    r, st = ev["randomized"], ev["stress_placement"]
    robust = f"""
## When the machine differs (`lhd eval --policy {shown}{run_cfg}{f' --episodes {episodes}' if episodes != 120 else ''} --seed {eval_seed} --randomize{' --deploy-filter' if deploy else ''}`, and with `--stress placement` in place of `--randomize`)

{dr_note} The same piles under drawn conditions ({drawn_conditions(cfg)}), and with the machine placed
by hand (heading +-3 deg, lip +-5 cm, camera errors, 100 ms dead time):

| condition | success | ASL | AML [kg] | elapsed [s] | restricted zone (of {r['episodes']}) | timeout | refused |
|---|---|---|---|---|---|---|---|
| randomised | {r['success_rate']:.3f} | {r['asl']:.2f} | {r['aml']:.1f} | {r['elapsed_s']:.2f} | {r['restricted_zone']} | {r['timeout']} | {r.get('refused', 0)} |
| placement corners | {st['success_rate']:.3f} | {st['asl']:.2f} | {st['aml']:.1f} | {st['elapsed_s']:.2f} | {st['restricted_zone']} | {st['timeout']} | {st.get('refused', 0)} |

Refused: episodes whose told slope (the pile's plus the drawn LiDAR error) lies outside the {lo_deg:g}-{hi_deg:g} deg the
actor was trained on; the policy node refuses them and the supervisor does not arm them, so they are not run and
count in the success as loading nothing; ASL, AML and time are over the attempts run.
"""
    gated_dirs = {c[1] for c in gated}
    filt = lambda e: (f"{e['with_deployment_filter']['success_rate']:.3f} | {e['with_deployment_filter']['asl']:.2f} | "  # noqa: E731
                      if deploy else "")
    seeds_rows = "\n".join(
        f"| {d.name} | {e['success_rate']:.3f} | {e['asl']:.2f} | {e['aml']:.1f} | {e['ar']:.0f} | {filt(e)}"
        f"{e.get('tilt_over_5deg_rate', float('nan')):.2f} | "
        f"{'shipped' if d == best_dir else 'left out: tilts the machine' if d in gated_dirs else ''} |"
        for _, d, _, e in cands)
    gate_note = (f" Seeds whose actor lifts the machine's rear over 5 deg in more than {max_tilt_rate:g} of the "
                 f"attempts were left out of the choice (`--max-tilt-rate {max_tilt_rate:g}`): "
                 + ", ".join(f"{c[1].name} ({c[3]['tilt_over_5deg_rate']:.2f})" for c in gated)
                 + f"; the median is that of the other {len(kept)}." if gated else "")
    unfinished_txt = ", ".join(unfinished)
    why = {"median": f"its final actor at step {m['steps']:,}; the median of {len(kept)} seeds on the held-out evaluation"
                     f"{f' ({len(gated)} more left out for tilting the machine)' if gated else ''}"
                     f"{f'; left out, training unfinished: {unfinished_txt}' if unfinished else ''}",
           "best": f"its best training-time evaluation at step {m['steps']:,}; the best of {len(cands)} seeds",
           "best-final": (f"its final actor at step {m['steps']:,}, no checkpoint picking; the best of {len(cands)} seeds' "
                          f"final actors on the held-out seed {HELD_OUT_SEED:,}: a selection, not what a retraining "
                          f"user should expect (see 'Across seeds')")}[select]
    tw = m.get("trained_with") if isinstance(m.get("trained_with"), dict) else {}
    margin = float(tw.get("r_success_pitch_margin_deg", 0.0) or 0.0)
    mass_margin = float(tw.get("r_success_mass_margin_kg", 0.0) or 0.0)
    margin_note = (f", and paid only above {40 + margin:g} deg (the training's pitch margin over the success test)"
                   if margin > 0 else "") + (
        f", and only from {20 + mass_margin:g} kg (the training's mass margin over the success test's 20 kg)"
        if mass_margin > 0 else "")
    tilt_per_deg = float(tw.get("r_tilt_per_deg", 0.0) or 0.0)
    tilt_free = float(tw.get("r_tilt_free_deg", 0.0) or 0.0)
    ramp_after = float(tw.get("r_tilt_ramp_after_success", 0.0) or 0.0)
    ramp_note = ""
    if tilt_per_deg > 0 and ramp_after > 0:
        start, weight = ramp_progress(best_dir, m)
        ramp_steps = int(tw.get("r_tilt_ramp_steps", 0))
        reached = ("; the ramp's start was not recorded" if weight is None else
                   "; the ramp never began: this actor was trained WITHOUT the penalty" if start is None else
                   f"; it began at step {start:,} and the actor has {weight:.0%} of the penalty")
        ramp_note = (f"; ramped in from 0 over {ramp_steps:,} steps once an evaluation succeeded in {ramp_after:g} "
                     f"of its episodes{', the success margins with it' if int(tw.get('r_tilt_ramp_pitch_margin', 0)) else ''}"
                     f"{reached}")
    tilt_name = (f" and a tilt penalty ({tilt_per_deg:g} per degree of the machine's pitch beyond {tilt_free:g} deg, "
                 f"every step{ramp_note})" if tilt_per_deg > 0 else "")
    tilt_note = (f"; and, not in the paper at all, r_tilt: -{tilt_per_deg:g} per degree of the machine's pitch "
                 f"beyond {tilt_free:g} deg at every step" if tilt_per_deg > 0 else "")
    n_departures = 4 + (margin > 0) + (mass_margin > 0)
    recipe = _recipe_note(tw)
    fin = summary["metrics"]
    card = f"""# {variant.upper()} loading policy ({'hybrid: continuous wheels, ternary arm' if variant == 'rld' else 'continuous actions, deployment filter on the machine'})

Actor exported from `{best_dir}/{sub}` (seed {m['seed']}, {why}), DDPG with the paper's protocol{' and domain randomisation' if trained_dr else ''}{f' and a {margin:g} deg pitch margin' if margin > 0 else ''}{f' and a {mass_margin:g} kg mass margin' if mass_margin > 0 else ''}{tilt_name}{recipe} (docs/training.md). Files: `actor.npz`
(float32 weights), `policy.json` (architecture {m['architecture']['sizes']}, observation and action
normalisation, filter thresholds, config hash `{m['config_hash']}`, training evaluation),
`evaluation.json` (the table below), `training_curves.png`{f", `{PARAMS_FILE}` (the parameter file it runs under)" if own_params else ""}.

Run it: `lhd up sim --policy {shown}{run_cfg}` or `ros2 run lhd_loading_ros policy_node --ros-args -p policy_dir:={shown}{node_cfg}`.{own_note}

Trained on piles of {lo_deg:g}-{hi_deg:g} deg (its observation normalises the slope over that range); the environment and the nodes refuse a slope outside it. The evaluations below are on the paper's {held_slopes} deg piles{other_piles}.

## Evaluation in simulation (`lhd eval --policy {shown}{run_cfg} --episodes {episodes} --seed {eval_seed}`{', piles that took no part in the selection' if select == 'best-final' else ', held-out seed'})

{_table(ev)}

Success: SL >= 1 at the end (>= 20 kg and final pitch > 40 deg), the paper's definition; the
end-zone column is the share of attempts that reached the end zone. Material, time and drift
are means over all attempts. {ev['failures']['restricted_zone']} attempts ended in the restricted zone,
{ev['failures']['timeout']} at the time limit. Tilt: the largest pitch of the machine's rear frame in an
attempt (the rear lifting in a breakout; docs/modeling.md "The machine's own tilt"), its mean and the
share of attempts above 5 deg.
{deploy_note}{robust}
## Across seeds

Held-out evaluation of each seed's {sub} actor ({'the shipped one is the median seed by success, then ASL, then AR' if select == 'median' else 'the shipped one is the best of them: not what a retraining user should expect'}{', with the deployment filter, as the policy node runs it' if deploy else ''}; seed {HELD_OUT_SEED:,}).{gate_note}

| seed | success | ASL | AML [kg] | AR | {'success with the filter | ASL with the filter | ' if deploy else ''}tilt > 5 deg | |
|---|---|---|---|---|{'---|---|' if deploy else ''}---|---|
{seeds_rows}

Final training-time evaluation (step {min(summary['final_steps']):,}, evaluation seed 1,000,000{', under the domain randomisation it trained with: every episode drawn, told slopes outside the range run clipped' if trained_dr else ''}), {len(runs)} seeds:
success {fin['success_rate']['mean']:.3f} ± {fin['success_rate']['sd']:.3f}, ASL {fin['asl']['mean']:.2f} ± {fin['asl']['sd']:.2f}
(IQM {fin['asl']['iqm']:.2f}, 95 % bootstrap interval [{fin['asl']['iqm_ci95'][0]:.2f}, {fin['asl']['iqm_ci95'][1]:.2f}]),
AML {fin['aml']['mean']:.1f} ± {fin['aml']['sd']:.1f} kg, AR {fin['ar']['mean']:.0f} ± {fin['ar']['sd']:.0f}.

![training curves](training_curves.png)

## Limits
Trained and evaluated in our simulator only (MuJoCo + extended FEE, gravel piles of {lo_deg:g}-{hi_deg:g}
deg, docs/modeling.md). The reward is the paper's with { {4: 'four', 5: 'five', 6: 'six'}[n_departures]} documented departures
(docs/training.md): r_success's pitch target 47.5 deg instead of 40 and paid only on a
successful attempt{margin_note}, r_weight paid on the material entering the bucket, and r_dump fining a
forward-tilted bucket (the paper's prose){tilt_note}.
Not yet run on the scaled machine.
"""
    (tmp / "README.md").write_text(card)
    return {"variant": variant, "shipped_from": str(best_dir / sub), "select": select, "evaluation": ev,
            "left_out_for_tilt": [str(c[1]) for c in gated],
            "summary": summary}
