"""Export a trained actor (FlatMlp) to a policy directory (see lhd_loading_ros.policy.actor_file)."""
from __future__ import annotations

from lhd_loading_ros.task.actions import ACT_NAMES
from lhd_loading_ros.task.config import config_hash
from lhd_loading_ros.task.observation import OBS_HIGH, OBS_LOW, OBS_NAMES, normalisers
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.policy.actor_file import save_policy
from lhd_loading_ros.learning.curriculum import CurriculumConfig
from lhd_loading_ros.learning.mlp import FlatMlp


def export_actor(directory, actor: FlatMlp, cfg: dict, meta: dict):
    p = TaskParams.from_config(cfg)
    curriculum = CurriculumConfig.from_training(cfg.get("training", {}))
    full = {
        "observation": {"names": list(OBS_NAMES), "low": OBS_LOW.tolist(), "high": OBS_HIGH.tolist(),
                        "normalization": "lhd_loading_ros.task.observation.build_observation (docs/modeling.md)",
                        # the constants it scaled by in training (SI, rad): the nodes refuse other ones
                        "normalisers": normalisers(p)},
        "action": {"names": list(ACT_NAMES), "range": [-1.0, 1.0],
                   "actuator_low": [p.wheels_min, p.boom_min, p.bucket_min],
                   "actuator_high": [p.wheels_max, p.boom_max, p.bucket_max], "actuator_units": "rad/s"},
        "filters": {"rld_threshold": p.rld_threshold, "rlc_boom_saturate": p.rlc_boom_saturate,
                    "rlc_bucket_saturate": p.rlc_bucket_saturate},
        # what the actor has seen in training: the nodes refuse inputs outside it (zero command and
        # a reason) instead of clipping them into range
        "trained_ranges": {"slope_deg": [cfg["paper"]["episode"]["alpha_min_deg"], cfg["paper"]["episode"]["alpha_max_deg"]]},
        "config_hash": config_hash(cfg),
        # training-only settings (task.config.TRAINING_ONLY): not in what the actor sees, but in its card
        "trained_with": {"randomize": bool(int(cfg.get("randomization", {}).get("enabled", 0))),
                         **({"twin_critics": 1} if int(cfg.get("training", {}).get("twin_critics", 0)) else {}),
                         **({"critic_huber": float(cfg["training"]["critic_huber"])}
                            if float(cfg.get("training", {}).get("critic_huber", 0.0)) > 0 else {}),
                         **({"actor_preact_l2": float(cfg["training"]["actor_preact_l2"])}
                            if float(cfg.get("training", {}).get("actor_preact_l2", 0.0)) > 0 else {}),
                         **({"demo_q_lower_bound": 1} if int(cfg.get("training", {}).get("demo_q_lower_bound", 0)) else {}),
                         **({"noise_after_decay": float(cfg["training"]["noise_after_decay"])}
                            if float(cfg.get("training", {}).get("noise_after_decay", 0.0)) > 0 else {}),
                         **({"slope_curriculum": curriculum.to_dict()} if curriculum is not None else {}),
                         **({"lr_final_scale": float(cfg["training"]["lr_final_scale"]),
                             "lr_decay_from": int(cfg["training"].get("lr_decay_from", 0))}
                            if float(cfg.get("training", {}).get("lr_final_scale", 1.0)) < 1.0 else {}),
                         **({"midgoal_from_pile": 1} if int(cfg["task"].get("midgoal_from_pile", 0)) else {}),
                         **({"reward_zones_from_pile": 1} if int(cfg["task"].get("reward_zones_from_pile", 0)) else {}),
                         **({"demonstrations": {k: cfg["training"][k] for k in
                                                ("demo_share", "demo_crowd_min", "demo_crowd_max", "demo_pre_curl")},
                             # the actor's Q-filtered behaviour cloning on them (training.demo_bc)
                             **({"demo_bc": float(cfg["training"]["demo_bc"])}
                                if float(cfg["training"].get("demo_bc", 0.0)) > 0 else {}),
                             # its filter: the demonstration's own return in place of the critic's Q(o, a)
                             **({"demo_bc_filter": "return"}
                                if int(cfg["training"].get("demo_bc_return_filter", 0)) else {}),
                             # the step demonstrations stop at (recorded only when not noise_decay_steps)
                             **({"demo_until_step": int(cfg["training"]["demo_until_step"])}
                                if int(cfg["training"].get("demo_until_step", 0)) > 0 else {}),
                             # the teacher reads the told zones, and stops its wheels in the end zone
                             **({"demo_told_zones": 1} if int(cfg["training"].get("demo_told_zones", 0)) else {}),
                             **({"demo_end_zone_stop": float(cfg["training"]["demo_end_zone_stop"])}
                                if float(cfg["training"].get("demo_end_zone_stop", 0.0)) > 0 else {}),
                             # the push-curl teacher (policy/maneuver.push_curl_action)
                             **{k: float(cfg["training"][k]) for k in ("demo_push_curl", "demo_late_lift", "demo_told_high",
                                                                      "demo_failing_share")
                                if float(cfg["training"].get(k, 0.0)) > 0},
                             # the demonstrations read the actor's drift flags and confirm one over this many steps
                             **({"demo_drift_confirm": int(cfg["training"]["demo_drift_confirm"])}
                                if int(cfg["training"].get("demo_drift_confirm", 1)) > 1 else {}),
                             # only on the slope bins where the teacher does at least as well as the actor
                             **({"demo_where_teacher_wins": 1}
                                if int(cfg["training"].get("demo_where_teacher_wins", 0)) else {})}
                            if float(cfg.get("training", {}).get("demo_share", 0.0)) > 0 else {}),
                         "r_success_pitch_margin_deg": float(cfg["task"].get("r_success_pitch_margin_deg", 0.0)),
                         **({"r_success_mass_margin_kg": float(cfg["task"]["r_success_mass_margin_kg"])}
                            if float(cfg["task"].get("r_success_mass_margin_kg", 0.0)) > 0 else {}),
                         "r_tilt_per_deg": float(cfg["task"].get("r_tilt_per_deg", 0.0)),
                         "r_tilt_free_deg": float(cfg["task"].get("r_tilt_free_deg", 0.0)),
                         **({"r_tilt_ramp_after_success": float(cfg["task"]["r_tilt_ramp_after_success"]),
                             "r_tilt_ramp_steps": int(cfg["task"].get("r_tilt_ramp_steps", 0)),
                             **({"r_tilt_ramp_pitch_margin": 1} if int(cfg["task"].get("r_tilt_ramp_pitch_margin", 0))
                                else {})}
                            if float(cfg["task"].get("r_tilt_per_deg", 0.0)) > 0
                            and float(cfg["task"].get("r_tilt_ramp_after_success", 0.0)) > 0 else {})},
        **meta,
    }
    return save_policy(directory, actor.numpy_weights(), full)
