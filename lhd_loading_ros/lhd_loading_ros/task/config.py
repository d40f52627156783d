"""Load and validate ``config/lhd_params.yaml``, the project's single source of parameters.

Every key has a type and a closed range. A missing, misspelt, mistyped or out-of-range
key raises :class:`ConfigError` with a message naming the key and what is expected.
"""
from __future__ import annotations

import difflib
import hashlib
import itertools
import json
import os
from pathlib import Path
from typing import Any

import yaml

INF = float("inf")


class ConfigError(ValueError):
    """The parameter file is not what the project expects."""


def _f(lo=-INF, hi=INF):
    return ("float", lo, hi)


def _i(lo=-INF, hi=INF):
    return ("int", lo, hi)


def _whole_chunks(value: float, chunk: float) -> bool:
    """Whether a duration is a whole number of chunks (within 1e-9 s)."""
    return abs(round(value / chunk) * chunk - value) <= 1e-9


def _ilist(lo=-INF, hi=INF, min_len=1, max_len=16):
    return ("intlist", lo, hi, min_len, max_len)


# (type, min, max) for every key. Ranges are physical or structural limits, not tuning advice.
SCHEMA: dict[str, Any] = {
    "paper": {
        "ddpg": {
            "actor_lr": _f(1e-7, 1.0), "critic_lr": _f(1e-7, 1.0), "gamma": _f(0.0, 0.9999),
            "replay_size": _i(1000, 10_000_000), "batch_size": _i(1, 65536), "tau": _f(1e-6, 1.0),
            "ou_mu": _f(-1.0, 1.0), "ou_sigma": _f(0.0, 5.0), "ou_theta": _f(0.0, 10.0), "ou_dt": _f(1e-4, 10.0),
        },
        "reward": {
            "R_zone": _f(0, 1e6), "R_traj": _f(0, 1e6), "R_drift": _f(0, 1e6), "R_bottom": _f(0, 1e6),
            "R_midgoal": _f(0, 1e6), "d_midgoal_max": _f(1e-3, 10.0),
            "R_stuck": _f(0, 1e6), "T_stuck": _i(1, 200), "delta_thresh": _f(0.0, 1.0),
            "R_inact": _f(0, 1e6), "u_thresh_boom": _f(0.0, 1.0), "u_thresh_bucket": _f(0.0, 1.0),
            "R_weight": _f(0, 1e6), "R_dump": _f(0, 1e6), "phi_thresh_pitch_deg": _f(-90, 90),
            "R_success": _f(0, 1e6), "W_target": _f(1e-3, 1e4), "phi_target_deg": _f(-90, 90),
            "rho_thresh_W": _f(1e-6, 1e3), "rho_thresh_phi_deg": _f(1e-6, 90),
        },
        "observation": {
            "d_end_max": _f(1e-3, 10.0), "x_init_obs": _f(0.0, 5.0), "x_obs": _f(1e-2, 10.0),
            "y_obs": _f(1e-2, 10.0), "z_obs": _f(1e-2, 10.0),
        },
        "control": {
            "frequency_hz": _f(0.1, 1000.0), "wheels_min": _f(0.0, 0.0), "wheels_max": _f(0.0, 100.0),
            "boom_min": _f(-10.0, 0.0), "boom_max": _f(0.0, 0.0),
            "bucket_min": _f(0.0, 0.0), "bucket_max": _f(0.0, 10.0),
        },
        "voxels": {"n_x": _i(2, 1000), "n_y": _i(1, 200), "n_z": _i(2, 1000)},
        "end_zone": {"m_min": _f(0.0, 1e5), "m_max": _f(0.0, 1e5), "z_min": _f(0.0, 5.0)},
        "episode": {
            "h_pile": _f(0.05, 10.0), "w_pile": _f(0.05, 10.0),
            "alpha_min_deg": _f(1.0, 60.0), "alpha_max_deg": _f(1.0, 60.0),
            "d_attack_min": _f(0.0, 5.0), "d_attack_max": _f(0.0, 5.0), "d_init": _f(0.0, 2.0),
            "max_steps": _i(1, 100000),
        },
    },
    "task": {
        "bucket_capacity": _f(0.1, 1e4), "loaded_fraction": _f(0.0, 1.0), "d_cutoff": _f(0.0, 5.0),
        "x_midgoal": _f(0.0, 10.0), "x_delta": _f(0.0, 5.0), "x_offset": _f(-10.0, 10.0),
        "z_offset": _f(-10.0, 10.0), "rail_exponent": _i(1, 99), "v_x_max": _f(1e-3, 20.0),
        "boom_angle_min": _f(-3.2, 0.0), "boom_angle_max": _f(0.0, 3.2),
        "bucket_angle_min": _f(-3.2, 0.0), "bucket_angle_max": _f(0.0, 3.2),
        "phi_shovel_min_deg": _f(-180, 0), "phi_shovel_max_deg": _f(0, 180),
        "drift_slip_ratio": _f(0.0, 1.0), "drift_min_speed": _f(0.0, 5.0),
        "rlc_boom_saturate": _f(-1.0, 1.0), "rlc_bucket_saturate": _f(-1.0, 1.0), "rld_threshold": _f(-1.0, 1.0),
        "r_dump_sign": _i(-1, 1), "r_weight_increments": _i(0, 1),
        "r_success_requires_sl": _i(0, 1), "success_pitch_margin_deg": _f(-45.0, 45.0),
        "r_success_pitch_margin_deg": _f(0.0, 20.0), "r_tilt_per_deg": _f(0.0, 1e4), "r_tilt_free_deg": _f(0.0, 45.0),
        "r_tilt_ramp_after_success": _f(0.0, 1.0), "r_tilt_ramp_steps": _i(0, 100_000_000),
        "r_tilt_ramp_pitch_margin": _i(0, 1), "r_success_mass_margin_kg": _f(0.0, 20.0),
        "bottom_tolerance": _f(0.0, 0.5),
        "bucket_repose_deg": _f(5.0, 60.0), "normalisers_from_pile": _i(0, 1),  # H4: capacity, derived normalisers
        "bucket_fill_factor": _f(0.0, 1.2),     # loader fill factor of the SAE rating; 0: none (2026-12-02)
        "midgoal_from_pile": _i(0, 1), "reward_zones_from_pile": _i(0, 1),
    },
    "machine": {
        "total_mass": _f(1.0, 1e5), "chassis_mass": _f(0.1, 1e5), "rear_mass_fraction": _f(0.05, 0.95),
        "rear_com_behind_axle": _f(-2.0, 2.0), "boom_mass": _f(0.1, 1e4),
        "bucket_mass": _f(0.1, 1e4), "wheel_mass": _f(0.01, 1e3), "wheel_radius": _f(0.01, 5.0),
        "wheelbase": _f(0.1, 20.0), "track": _f(0.1, 10.0), "wheel_friction": _f(0.05, 3.0),
        "wheel_torque_limit": _f(0.1, 1e5), "wheel_kv": _f(0.1, 1e5), "motor_armature": _f(1e-5, 100.0),
        "rear_differential": _i(0, 1),
        "boom_pivot_ahead_of_front_axle": _f(-2.0, 5.0), "boom_pivot_height": _f(0.05, 5.0),
        "boom_length": _f(0.05, 10.0), "bucket_hinge_height": _f(0.01, 5.0),
        "bucket_tip_ahead_of_hinge": _f(0.01, 5.0), "bucket_width": _f(0.05, 10.0),
        "bucket_back_height": _f(0.01, 5.0), "boom_force_limit": _f(1.0, 1e7), "boom_kp": _f(1.0, 1e8), "boom_kv": _f(1.0, 1e7),
        "bucket_force_limit": _f(1.0, 1e7), "bucket_kp": _f(1.0, 1e8), "bucket_kv": _f(1.0, 1e7), "bucket_floor_friction": _f(0.0, 3.0),
    },
    "pile": {
        "density_min": _f(500, 5000), "density_max": _f(500, 5000),
        "phi_min_deg": _f(5, 60), "phi_max_deg": _f(5, 60), "delta_min_deg": _f(0, 45), "delta_max_deg": _f(0, 45),
        "cohesion_min": _f(0, 1e6), "cohesion_max": _f(0, 1e6), "adhesion": _f(0, 1e6),
        "surcharge_min": _f(0, 1e7), "surcharge_max": _f(0, 1e7),
        "rock_density": _f(500, 6000), "rock_phi_deg": _f(5, 60), "rock_delta_deg": _f(0, 45),
        "rock_size_min": _f(0.001, 2.0), "rock_size_max": _f(0.001, 2.0),
        "rocks_min": _i(0, 1000), "rocks_max": _i(0, 1000), "nonhomogeneous_probability": _f(0.0, 1.0),
        "rake_attack_deg": _f(1, 179), "rake_min_deg": _f(1, 179), "rake_max_deg": _f(1, 179),
        "fee_min_speed": _f(1e-4, 1.0), "fee_wedge_by_motion": _i(0, 1), "fee_wedge_tau": _f(0.0, 10.0),
    },
    "hardware": {
        "valve_deadband": _f(0.0, 1.0), "cmd_timeout": _f(0.01, 10.0), "command_rate_hz": _f(1.0, 1000.0),
        "device_watchdog": _f(0.01, 10.0), "sensor_rate_hz": _f(1.0, 2000.0),
        "drift_current_front": _f(0.0, 200.0), "drift_current_rear": _f(0.0, 200.0), "odom_timeout": _f(0.01, 10.0),
        "reconnect_backoff_min": _f(0.001, 10.0), "reconnect_backoff_max": _f(0.001, 60.0),
    },
    "sim": {"timestep": _f(1e-4, 0.05), "fee_every": _i(1, 1000), "attack_timeout": _f(0.1, 100.0),
            "attack_speed_min_fraction": _f(0.05, 1.0), "attack_min_depth": _f(0.0, 1.0)},
    "bucket_body": {"enabled": _i(0, 1), "k_uplift": _f(0.0, 3.0)},  # the whole bucket in the pile (bucket_body.py)
    "randomization": {  # issue 14, task/randomization.py
        "enabled": _i(0, 1), "slope_error_max_deg": _f(0.0, 45.0), "slope_noise_deg": _f(0.0, 10.0),
        "vx_noise": _f(0.0, 1.0), "vx_dropout_probability": _f(0.0, 1.0), "vx_dropout_max_steps": _i(0, 100),
        "vx_delay_steps_max": _i(0, 10), "actuator_delay_max_s": _f(0.0, 1.0),
        "density_min": _f(100.0, 6000.0), "density_max": _f(100.0, 6000.0),
        "phi_min_deg": _f(5.0, 60.0), "phi_max_deg": _f(5.0, 60.0), "cohesion_max": _f(0.0, 1e6),
        "rocks_max": _i(0, 1000), "tyre_friction_min": _f(0.05, 3.0), "tyre_friction_max": _f(0.05, 3.0),
        "d_attack_max": _f(0.0, 5.0), "attack_speed_min_fraction": _f(0.05, 1.0),
        "heading_max_deg": _f(0.0, 45.0), "lateral_offset_max": _f(0.0, 1.0),
        "drive_gain_min": _f(0.1, 2.0), "drive_gain_max": _f(0.1, 2.0),
        "hydraulic_gain_min": _f(0.1, 2.0), "hydraulic_gain_max": _f(0.1, 2.0),
        "zones_from_slope_estimate": _i(0, 1), "rest_start_share": _f(0.0, 1.0),
        "surface_sd_max": _f(0.0, 0.2), "zones_at_nominal_density": _i(0, 1), "arm_offset_max_deg": _f(0.0, 10.0),
        "slope_error_high_share": _f(0.0, 1.0), "drift_flag_lag_max_s": _f(0.0, 0.5),
        "slope_error_small_share": _f(0.0, 1.0), "slope_error_small_max_deg": _f(0.0, 45.0),
    },
    "training": {
        "total_steps": _i(1, 100_000_000), "noise_decay_steps": _i(0, 100_000_000), "noise_final_scale": _f(0.0, 1.0),
        "learning_starts": _i(1, 10_000_000), "hidden_sizes": _ilist(1, 4096, 1, 8), "reward_scale": _f(1e-6, 1e3),
        "eval_every": _i(1, 100_000_000), "eval_episodes": _i(1, 100_000), "eval_seed": _i(0, 2**31 - 1),
        "checkpoint_every": _i(1, 100_000_000), "torch_threads": _i(1, 256),
        "twin_critics": _i(0, 1), "slope_curriculum": _i(0, 1), "slope_curriculum_bins": _i(1, 100),
        "slope_curriculum_window": _i(1, 100_000), "slope_curriculum_uniform": _f(0.01, 1.0),
        "slope_curriculum_reward_test": _i(0, 1),
        "lr_final_scale": _f(0.01, 1.0), "lr_decay_from": _i(0, 100_000_000),
        "demo_share": _f(0.0, 0.9), "demo_crowd_min": _f(0.05, 1.0), "demo_crowd_max": _f(0.05, 1.0),
        "demo_pre_curl": _f(0.0, 1.4), "demo_bc": _f(0.0, 100.0), "demo_until_step": _i(0, 100_000_000),
        "critic_huber": _f(0.0, 1e6), "noise_after_decay": _f(0.0, 1.0), "demo_bc_return_filter": _i(0, 1),
        "actor_preact_l2": _f(0.0, 10.0),
        "demo_q_lower_bound": _i(0, 1),
        "demo_told_zones": _i(0, 1), "demo_end_zone_stop": _f(0.0, 1.0),
        "demo_push_curl": _f(0.0, 1.4), "demo_late_lift": _f(0.0, 1.0), "demo_told_high": _f(0.0, 45.0),
        "demo_drift_confirm": _i(1, 50), "demo_failing_share": _f(0.0, 0.9), "demo_where_teacher_wins": _i(0, 1), "episode_seed_offset": _i(0, 2**31 - 2),
    },
}

def _physics_steps(c: dict) -> float:
    """MuJoCo steps in a control period (the simulator needs a whole number)."""
    return 1.0 / c["paper"]["control"]["frequency_hz"] / c["sim"]["timestep"]


def _whole(x: float) -> bool:
    return abs(x - round(x)) <= 1e-6


# Relations between keys: (description, predicate).
HELD_OUT_SEEDS = (2_000_000, 4_000_000)   # [first, end) of the held-out evaluations' episode seeds (_RELATIONS)
_RELATIONS = [
    # the simulator's own checks (simulator.py), said here so that `lhd config check` and every
    # command refuse such a file with one line instead of a traceback from the simulator (a review)
    ("sim.timestep divides the control period 1 / paper.control.frequency_hz into whole physics steps (0.004 s "
     "into 0.1 s: 25)", lambda c: _whole(_physics_steps(c))),
    ("sim.fee_every divides the physics steps of a control period (5 of 25)",
     lambda c: not _whole(_physics_steps(c)) or round(_physics_steps(c)) % c["sim"]["fee_every"] == 0),
    ("training.demo_bc_return_filter = 1 only with training.demo_bc > 0 (it chooses which demonstration rows are "
     "cloned)", lambda c: not c["training"]["demo_bc_return_filter"] or c["training"]["demo_bc"] > 0.0),
    ("training.demo_q_lower_bound = 1 only with training.demo_bc > 0 and training.demo_bc_return_filter = 1 (the "
     "demonstrations' returns it bounds the critics' target by are stored for the return filter)",
     lambda c: not c["training"]["demo_q_lower_bound"] or (c["training"]["demo_bc"] > 0.0
                                                           and bool(c["training"]["demo_bc_return_filter"]))),
    # without demo_share there are no demonstrations at all (DemoConfig is off): the key would do nothing, silently
    ("training.demo_told_high > 0 only with training.demo_share > 0 (it makes told-high episodes demonstrations; "
     "the demonstrations are off at demo_share 0)",
     lambda c: not c["training"]["demo_told_high"] > 0.0 or c["training"]["demo_share"] > 0.0),
    ("training.demo_failing_share > 0 only with training.demo_share > 0 and training.slope_curriculum = 1 (it makes "
     "episodes of the slope bins the curriculum counts failing demonstrations)",
     lambda c: not c["training"]["demo_failing_share"] > 0.0
     or (c["training"]["demo_share"] > 0.0 and int(c["training"]["slope_curriculum"]) == 1)),
    ("training.demo_where_teacher_wins = 1 only with training.demo_share > 0 and training.slope_curriculum = 1 (it "
     "compares the teacher's and the actor's success on the curriculum's slope bins)",
     lambda c: not int(c["training"]["demo_where_teacher_wins"])
     or (c["training"]["demo_share"] > 0.0 and int(c["training"]["slope_curriculum"]) == 1)),
    ("training.demo_drift_confirm > 1 only with training.demo_share > 0 (it sets how the demonstrations read a drift "
     "flag; the demonstrations are off at demo_share 0)",
     lambda c: c["training"]["demo_drift_confirm"] <= 1 or c["training"]["demo_share"] > 0.0),
    # a told error of at least demo_told_high is never drawn where the slope error stays below it: silent again
    ("training.demo_told_high <= randomization.slope_error_max_deg (no episode is told more than slope_error_max_deg "
     "too steep, so none would be a told-high demonstration)",
     lambda c: c["training"]["demo_told_high"] <= c["randomization"]["slope_error_max_deg"]),
    # the small error is the LiDAR's right estimate inside the whole range's; a share drawn from an empty range
    # would only zero the error, which slope_error_small_max_deg 0 says nowhere
    ("randomization.slope_error_small_max_deg <= randomization.slope_error_max_deg, and > 0 where "
     "randomization.slope_error_small_share > 0 (the share draws its error U(-small_max, small_max))",
     lambda c: c["randomization"]["slope_error_small_max_deg"] <= c["randomization"]["slope_error_max_deg"]
     and (not c["randomization"]["slope_error_small_share"] > 0.0 or c["randomization"]["slope_error_small_max_deg"] > 0.0)),
    # with neither, the told zones are the pile's own and the reward reads the same zones either way
    ("task.reward_zones_from_pile = 1 only with randomization.zones_from_slope_estimate = 1 or "
     "randomization.zones_at_nominal_density = 1 (otherwise the told zones are the pile's own and the key does nothing)",
     lambda c: not c["task"]["reward_zones_from_pile"] or c["randomization"]["zones_from_slope_estimate"]
     or c["randomization"]["zones_at_nominal_density"]),
    ("training.demo_crowd_min <= training.demo_crowd_max",
     lambda c: c["training"]["demo_crowd_min"] <= c["training"]["demo_crowd_max"]),
    ("paper.end_zone.m_min < paper.end_zone.m_max", lambda c: c["paper"]["end_zone"]["m_min"] < c["paper"]["end_zone"]["m_max"]),
    ("paper.episode.alpha_min_deg < paper.episode.alpha_max_deg",
     lambda c: c["paper"]["episode"]["alpha_min_deg"] < c["paper"]["episode"]["alpha_max_deg"]),
    # a dry granular pile stands at most at its angle of repose, which for a cohesionless pile is its
    # internal friction angle (Terzaghi, Peck & Mesri, Soil Mechanics in Engineering Practice, 3rd ed.,
    # art. 16): a face steeper than pile.phi_max_deg would slide, and the simulator would still resist
    # the bucket with it (a review: a 30 deg pile of 5 deg soil pitched the machine 47 deg nose-down)
    ("paper.episode.alpha_max_deg <= pile.phi_max_deg (a pile's face stands at most at its angle of repose, "
     "the friction angle of a cohesionless pile)",
     lambda c: c["paper"]["episode"]["alpha_max_deg"] <= c["pile"]["phi_max_deg"]),
    ("paper.episode.alpha_max_deg <= randomization.phi_max_deg (a randomised pile's material must stand at the "
     "steepest slope too; each pile draws its friction angle from [max(phi_min, slope), phi_max])",
     lambda c: c["paper"]["episode"]["alpha_max_deg"] <= c["randomization"]["phi_max_deg"]),
    ("sim.attack_min_depth <= paper.episode.d_init (0: the attack must reach d_init; else the least depth a "
     "stalled attack may start from)",
     lambda c: c["sim"]["attack_min_depth"] <= c["paper"]["episode"]["d_init"]),
    ("task.bucket_fill_factor is 0 (none) or within the bucket's struck share and its static heap at task.bucket_repose_deg "
     "(0.749-1.100 of the SAE heaped rating for the paper's bucket at 35 deg; task/bucket_capacity.fill_scale)",
     lambda c: _fill_factor_ok(c)),
    ("paper.episode.d_attack_min <= paper.episode.d_attack_max",
     lambda c: c["paper"]["episode"]["d_attack_min"] <= c["paper"]["episode"]["d_attack_max"]),
    ("hardware.reconnect_backoff_min <= hardware.reconnect_backoff_max",
     lambda c: c["hardware"]["reconnect_backoff_min"] <= c["hardware"]["reconnect_backoff_max"]),
    ("pile.density_min <= pile.density_max", lambda c: c["pile"]["density_min"] <= c["pile"]["density_max"]),
    ("pile.phi_min_deg <= pile.phi_max_deg", lambda c: c["pile"]["phi_min_deg"] <= c["pile"]["phi_max_deg"]),
    ("pile.delta_min_deg <= pile.delta_max_deg", lambda c: c["pile"]["delta_min_deg"] <= c["pile"]["delta_max_deg"]),
    ("pile.cohesion_min <= pile.cohesion_max", lambda c: c["pile"]["cohesion_min"] <= c["pile"]["cohesion_max"]),
    ("pile.surcharge_min <= pile.surcharge_max", lambda c: c["pile"]["surcharge_min"] <= c["pile"]["surcharge_max"]),
    ("pile.rock_size_min <= pile.rock_size_max", lambda c: c["pile"]["rock_size_min"] <= c["pile"]["rock_size_max"]),
    ("pile.rocks_min <= pile.rocks_max", lambda c: c["pile"]["rocks_min"] <= c["pile"]["rocks_max"]),
    ("pile.rake_min_deg <= pile.rake_attack_deg <= pile.rake_max_deg",
     lambda c: c["pile"]["rake_min_deg"] <= c["pile"]["rake_attack_deg"] <= c["pile"]["rake_max_deg"]),
    ("machine.bucket_hinge_height < machine.boom_pivot_height",
     lambda c: c["machine"]["bucket_hinge_height"] < c["machine"]["boom_pivot_height"]),
    ("machine.boom_pivot_height - machine.bucket_hinge_height < machine.boom_length",
     lambda c: c["machine"]["boom_pivot_height"] - c["machine"]["bucket_hinge_height"] < c["machine"]["boom_length"]),
    ("machine masses add up to machine.total_mass within 1 kg",
     lambda c: abs(c["machine"]["chassis_mass"] + c["machine"]["boom_mass"] + c["machine"]["bucket_mass"]
                   + 4 * c["machine"]["wheel_mass"] - c["machine"]["total_mass"]) <= 1.0),
    ("paper.control.wheels_max * machine.wheel_radius < task.v_x_max",
     lambda c: c["paper"]["control"]["wheels_max"] * c["machine"]["wheel_radius"] < c["task"]["v_x_max"]),
    ("task.r_dump_sign is -1 or +1", lambda c: c["task"]["r_dump_sign"] in (-1, 1)),
    ("randomization.density_min <= randomization.density_max",
     lambda c: c["randomization"]["density_min"] <= c["randomization"]["density_max"]),
    ("randomization.phi_min_deg <= randomization.phi_max_deg",
     lambda c: c["randomization"]["phi_min_deg"] <= c["randomization"]["phi_max_deg"]),
    ("randomization.tyre_friction_min <= randomization.tyre_friction_max",
     lambda c: c["randomization"]["tyre_friction_min"] <= c["randomization"]["tyre_friction_max"]),
    ("randomization.drive_gain_min <= randomization.drive_gain_max",
     lambda c: c["randomization"]["drive_gain_min"] <= c["randomization"]["drive_gain_max"]),
    ("randomization.hydraulic_gain_min <= randomization.hydraulic_gain_max",
     lambda c: c["randomization"]["hydraulic_gain_min"] <= c["randomization"]["hydraulic_gain_max"]),
    ("randomization.drift_flag_lag_max_s is a whole number of FEE chunks (sim.timestep x sim.fee_every, 0.02 s shipped)",
     lambda c: _whole_chunks(c["randomization"].get("drift_flag_lag_max_s", 0.0), c["sim"]["timestep"] * c["sim"]["fee_every"])),
    ("paper.episode.d_attack_min <= randomization.d_attack_max",
     lambda c: c["paper"]["episode"]["d_attack_min"] <= c["randomization"]["d_attack_max"]),
    ("randomization.rocks_max >= pile.rocks_min", lambda c: c["randomization"]["rocks_max"] >= c["pile"]["rocks_min"]),
    ("training.noise_decay_steps <= training.total_steps",
     lambda c: c["training"]["noise_decay_steps"] <= c["training"]["total_steps"]),
    ("training.learning_starts >= paper.ddpg.batch_size",
     lambda c: c["training"]["learning_starts"] >= c["paper"]["ddpg"]["batch_size"]),
    # the training's episode seeds start at the offset (learning/train.episode_seed): with one, the periodic
    # evaluation's piles lie below it, as do the held-out seeds of lhd eval / report / ship (2,000,000 and 3,000,000)
    ("training.eval_seed + training.eval_episodes <= training.episode_seed_offset, where the offset is not 0 (the "
     "periodic evaluation's piles apart from the training's)",
     lambda c: int(c["training"].get("episode_seed_offset", 0)) == 0
     or c["training"]["eval_seed"] + c["training"]["eval_episodes"] <= c["training"]["episode_seed_offset"]),
    # the held-out evaluations' piles (lhd eval / report --held-out / ship from 2,000,000; ship's confirmation seed and
    # lhd experiment paper from 3,000,000): the periodic evaluation, which picks best/, must not have seen them
    ("training.eval_seed .. eval_seed + eval_episodes lies outside the held-out evaluation seeds 2,000,000-3,999,999 "
     "(lhd eval / report --held-out / ship: 2,000,000; ship's confirmation and lhd experiment paper: 3,000,000)",
     lambda c: not (c["training"]["eval_seed"] < HELD_OUT_SEEDS[1]
                    and c["training"]["eval_seed"] + c["training"]["eval_episodes"] > HELD_OUT_SEEDS[0])),
]


def _check(node: Any, schema: Any, path: str, errors: list[str]) -> None:
    if not isinstance(node, dict):
        errors.append(f"'{path}' must be a mapping of keys, got {type(node).__name__}")
        return
    for key in node:
        if key not in schema:
            close = difflib.get_close_matches(str(key), list(schema), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            errors.append(f"unknown key '{path}{key}'{hint}; expected one of: {', '.join(schema)}")
    for key, spec in schema.items():
        full = f"{path}{key}"
        if key not in node:
            errors.append(f"missing key '{full}'" + ("" if isinstance(spec, dict) else f" (expected {_describe(spec)})"))
            continue
        val = node[key]
        if isinstance(spec, dict):
            _check(val, spec, full + ".", errors)
            continue
        kind, lo, hi = spec[:3]
        if kind == "intlist":
            min_len, max_len = spec[3:]
            ok = (isinstance(val, list) and min_len <= len(val) <= max_len
                  and all(isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi for v in val))
            if not ok:
                errors.append(f"'{full}' = {val!r} is not valid; expected {_describe(spec)}")
            continue
        if kind == "float" and isinstance(val, str):
            # PyYAML reads 1e-4 (no dot in the mantissa) as a string, not a number (YAML 1.1): a float field
            # takes a string that is a number (an int field, or a list, does not)
            try:
                val = node[key] = float(val.strip())
            except ValueError:
                pass
        if isinstance(val, bool) or not isinstance(val, (int, float)):
            errors.append(f"'{full}' = {val!r} is not a number; expected {_describe(spec)}")
            continue
        if kind == "int" and not float(val).is_integer():
            errors.append(f"'{full}' = {val!r} must be an integer; expected {_describe(spec)}")
            continue
        if not (lo <= val <= hi) or val != val:
            errors.append(f"'{full}' = {val!r} is out of range; expected {_describe(spec)}")


def _describe(spec) -> str:
    kind, lo, hi = spec[:3]
    if kind == "intlist":
        return f"a list of {spec[3]} to {spec[4]} integers in [{lo:g}, {hi:g}]"
    return f"{kind} in [{lo:g}, {hi:g}]"


# Keys a parameter file may leave out, with the value they then take: how the learner learns
# (never in the config hash, TRAINING_SCHEDULE_KEYS) and r_success's mass margin (never in it
# either), added after parameter files were written that trained fine without them; and machine.rear_differential, whose absence means the
# simulator before it (SIM_CHANGES: every wheel its own motor), as in the parameter files of the
# evidence written before it. Every other key is required.
OPTIONAL_DEFAULTS = {("training", "twin_critics"): 0, ("training", "slope_curriculum"): 0,
                     ("training", "slope_curriculum_bins"): 6, ("training", "slope_curriculum_window"): 100,
                     ("training", "slope_curriculum_uniform"): 0.5, ("training", "lr_final_scale"): 1.0,
                     ("training", "slope_curriculum_reward_test"): 0,
                     ("training", "lr_decay_from"): 0, ("machine", "rear_differential"): 0,
                     ("task", "midgoal_from_pile"): 0, ("task", "reward_zones_from_pile"): 0,
                     ("training", "demo_share"): 0.0,
                     ("training", "demo_crowd_min"): 0.5, ("training", "demo_crowd_max"): 0.75,
                     ("training", "demo_pre_curl"): 0.3, ("training", "demo_bc"): 0.0,
                     ("training", "demo_until_step"): 0, ("training", "critic_huber"): 0.0,
                     ("training", "noise_after_decay"): 0.0, ("task", "r_success_mass_margin_kg"): 0.0,
                     ("training", "demo_bc_return_filter"): 0,
                     # 0: no penalty on the actor's tanh input, as every run before 2026-12-02 (thirty-fifth session)
                     ("training", "actor_preact_l2"): 0.0,
                     # 0: the critics' target the one-step TD target on every row, as every run before 2026-12-02
                     ("training", "demo_q_lower_bound"): 0,
                     # 0: the training's episode seeds run_seed * 1,000,003 + k, as every run before 2026-11-29
                     # (twelfth session) drew them; run seeds 1-3 then shared their first ~115 piles with the
                     # evaluation seeds 1,000,000 / 2,000,000 / 3,000,000 (learning/train.episode_seed)
                     ("training", "episode_seed_offset"): 0,
                     # 0: an attack drive that stalls short of d_init is an AttackError (every file before
                     # 2026-11-29, fifteenth session); > 0: it starts the episode where it stalled, if the tip is this
                     # far inside the pile (lhd_sim_node/simulator.py reset; docs/modeling.md "Piles steeper than gravel")
                     ("sim", "attack_min_depth"): 0.0,
                     # 0: no fill factor, the bucket holds the whole static heap (task/bucket_capacity.py), as every
                     # file before 2026-12-02 (thirty-seventh session; SIM_CHANGES)
                     ("task", "bucket_fill_factor"): 0.0,
                     # the demonstrations read the told zones and stop in the end zone (learning/demonstrations.py)
                     ("training", "demo_told_zones"): 0, ("training", "demo_end_zone_stop"): 0.0,
                     # the push-curl teacher (policy/maneuver.push_curl_action, 2026-11-30); 0: the level push
                     ("training", "demo_push_curl"): 0.0, ("training", "demo_late_lift"): 0.0,
                     # every episode told this many deg too steep a demonstration (2026-11-30); 0: demo_share's only
                     ("training", "demo_told_high"): 0.0,
                     # decisions a drift flag the actor sees holds before the demonstration lifts (2026-12-01); 1: at once
                     ("training", "demo_drift_confirm"): 1,
                     # an actor's episode on a failing slope bin a demonstration with probability this x the bin's
                     # failure rate (2026-12-01, twenty-seventh session); 0: demo_share's only
                     ("training", "demo_failing_share"): 0.0,
                     # demonstrations only on the slope bins where the teacher does at least as well as the actor
                     # (2026-12-02, thirty-fourth session); 0: wherever the keys above make them
                     ("training", "demo_where_teacher_wins"): 0,
                     # actuator gains drawn per episode (task/randomization.py); 1 = the simulator's actuators
                     ("randomization", "drive_gain_min"): 1.0, ("randomization", "drive_gain_max"): 1.0,
                     ("randomization", "hydraulic_gain_min"): 1.0, ("randomization", "hydraulic_gain_max"): 1.0,
                     }
# Randomisation keys added after randomised actors were trained, each with the value that does what training
# did before the key existed. At that value the key is left out of the config hash (those actors keep theirs),
# and training_variants tries both it and a config's own value (an actor trained either way runs on the config).
# One table for OPTIONAL_DEFAULTS, config_hash and training_variants: a new such key goes here only.
RANDOMIZATION_LATER_KEYS = (
    # 0: a slope-estimate error reached the observed alpha only, not the zones built from it
    # (before 2026-11-28; task/zones.zones_for_slope_estimate)
    ("zones_from_slope_estimate", 0),
    # 0: every episode starts at the attack speed (the paper's), none from rest (2026-11-29)
    ("rest_start_share", 0.0),
    # 0: every pile's surface a plane in training (before the key existed, 2026-11-29)
    ("surface_sd_max", 0.0),
    # 0: the zones of the pile in front of the machine (its own density and rocks); 1: the
    # end-zone node's wedge at the nominal density (task/end_zone.zones_at_nominal_density; 2026-11-29)
    ("zones_at_nominal_density", 0),
    # 0: the arm's angle sensors read the true angles in training (before the key, 2026-11-29)
    ("arm_offset_max_deg", 0.0),
    # 0: the slope error U(-max, max) in every episode (before the key, 2026-11-30)
    ("slope_error_high_share", 0.0),
    # 0: the observed drift flag over the control period since the last command, the simulator's own
    # window (before the key, 2026-11-30; LhdSimulator.drift_flag)
    ("drift_flag_lag_max_s", 0.0),
    # 0: the slope error U(-max, max) in every episode, none drawn small as the LiDAR gives it (before the key,
    # 2026-12-02); the small range is read only with the share on
    ("slope_error_small_share", 0.0),
    ("slope_error_small_max_deg", 0.0),
)
OPTIONAL_DEFAULTS.update({("randomization", k): v for k, v in RANDOMIZATION_LATER_KEYS})


def _same(value, default) -> bool:
    """Whether a config value is a RANDOMIZATION_LATER_KEYS default (compared as the default's type)."""
    return type(default)(value) == default


ACTUATOR_GAIN_KEYS = ("drive_gain_min", "drive_gain_max", "hydraulic_gain_min", "hydraulic_gain_max")


MAX_LISTED_ERRORS = 12


def _error_message(errors: list[str]) -> str:
    """The ConfigError text: the first MAX_LISTED_ERRORS problems and how many more, and, where keys
    are missing, that a parameter file is complete (not an overlay of the default)."""
    shown = errors[:MAX_LISTED_ERRORS]
    msg = "invalid LHD parameters:\n  - " + "\n  - ".join(shown)
    if len(errors) > len(shown):
        msg += f"\n  ... and {len(errors) - len(shown)} more"
    missing = sum(e.startswith("missing key") for e in errors)
    if missing:
        msg += (f"\n({missing} missing keys: a parameter file is complete, not an overlay of the default; copy "
                f"config/lhd_params.yaml, or the actor's own lhd_params.yaml, and change the values you need)")
    return msg


def _fill_factor_ok(cfg: dict) -> bool:
    """task.bucket_fill_factor within what the config's bucket can hold (task/bucket_capacity.fill_scale)."""
    if float(cfg["task"].get("bucket_fill_factor", 0.0)) == 0.0:
        return True
    from lhd_loading_ros.task.bucket_capacity import fill_scale   # geometry; imported here, it needs no config
    try:
        fill_scale(cfg)
    except ValueError:
        return False
    return True


def validate(cfg: Any) -> dict:
    """Validate a parsed config mapping; return it with ints converted and the keys of
    OPTIONAL_DEFAULTS it left out filled in. Raises ConfigError."""
    errors: list[str] = []
    if isinstance(cfg, dict):
        for (section, key), value in OPTIONAL_DEFAULTS.items():
            if isinstance(cfg.get(section), dict):
                cfg[section].setdefault(key, value)
    _check(cfg, SCHEMA, "", errors)
    if not errors:
        for desc, pred in _RELATIONS:
            if not pred(cfg):
                errors.append(f"relation violated: {desc}")
    if errors:
        raise ConfigError(_error_message(errors))
    _coerce(cfg, SCHEMA)
    return cfg


def _coerce(node, schema):
    for key, spec in schema.items():
        if isinstance(spec, dict):
            _coerce(node[key], spec)
        elif spec[0] == "intlist":
            node[key] = [int(v) for v in node[key]]
        elif spec[0] == "int":
            node[key] = int(node[key])
        else:
            node[key] = float(node[key])


def config_name(config: str | os.PathLike | None) -> str:
    """How a message names the parameter file load_config(config) reads: the path given, else
    $LHD_CONFIG's (so named), else the source tree's config/lhd_params.yaml."""
    if config:
        return str(config)
    env = os.environ.get("LHD_CONFIG")
    return f"{env} ($LHD_CONFIG)" if env else "config/lhd_params.yaml"


def default_config_path() -> Path:
    """$LHD_CONFIG, else config/lhd_params.yaml of the source tree, else the installed share copy."""
    env = os.environ.get("LHD_CONFIG")
    if env:
        return Path(env)
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / "config" / "lhd_params.yaml"
        if cand.is_file():
            return cand
    try:  # colcon install: share/lhd_loading_ros/config
        from ament_index_python.packages import get_package_share_directory

        cand = Path(get_package_share_directory("lhd_loading_ros")) / "config" / "lhd_params.yaml"
        if cand.is_file():
            return cand
    except Exception:  # noqa: BLE001 - ament index absent or package not installed there
        pass
    raise ConfigError("cannot find config/lhd_params.yaml: set LHD_CONFIG to its path")


def load_config(path: str | os.PathLike | None = None) -> dict:
    """Read and validate the parameter file (default: :func:`default_config_path`)."""
    p = Path(path) if path is not None else default_config_path()
    try:
        text = p.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read parameter file {p}: {exc}") from exc
    try:
        cfg = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{p} is not valid YAML: {exc}") from exc
    if cfg is None:
        raise ConfigError(f"{p} is empty (or only comments); expected the parameter file's sections (paper, task, "
                          f"...), as in {default_config_path()}")
    try:
        return validate(cfg)
    except ConfigError as exc:
        raise ConfigError(f"{p}: {exc}") from None


# Settings that change what an actor was TRAINED on but not what it sees or commands (the
# observation, the normalisers, the filters): the nodes may run an actor trained with other values
# (hash_matches). (section, key, neutral value): at its neutral value each is left out of the hash
# (config_hash), so actors trained before it existed keep theirs; randomization.enabled = 0 drops
# the whole randomization section, whose ranges mean nothing while it is off.
TRAINING_ONLY = (("randomization", "enabled", 0), ("task", "r_success_pitch_margin_deg", 0.0),
                 ("task", "r_tilt_per_deg", 0.0))
TILT_KEYS = ("r_tilt_per_deg", "r_tilt_free_deg")     # the tilt penalty; both left out of the hash while it is off
# the tilt penalty's schedule in training (learning/ddpg.TiltRamp): never in the hash, like the
# penalty itself a reward setting, not what the actor sees. It does decide how much of the penalty
# an actor was trained with (all of it once the ramp is through; none if it never began): the card
# records the schedule and that weight (learning/ship.py), and `lhd ship` warns below the whole
TILT_SCHEDULE_KEYS = ("r_tilt_ramp_after_success", "r_tilt_ramp_steps", "r_tilt_ramp_pitch_margin",
                      # r_success's mass margin over the success test's 20 kg: a reward setting (what r_success
                      # asks of the load), not what the actor sees; the card's trained_with records it
                      "r_success_mass_margin_kg",
                      # where r_midgoal / r_inact switch (the paper's constant x_midgoal, or the episode pile's
                      # x_min): reward shaping, not what the actor sees; the card's trained_with records it
                      "midgoal_from_pile",
                      # the zones the reward's shaping terms read (the told ones, or the pile's own): likewise
                      "reward_zones_from_pile")
# how the learner learned (never in the hash; the card's trained_with records them): clipped double Q
# and the slope curriculum (learning/curriculum.py), which draws training piles, never evaluation ones
TRAINING_SCHEDULE_KEYS = ("twin_critics", "slope_curriculum", "slope_curriculum_bins", "slope_curriculum_window",
                          "slope_curriculum_uniform", "slope_curriculum_reward_test", "lr_final_scale", "lr_decay_from",
                          # scripted demonstrations in the replay (learning/demonstrations.py)
                          "demo_share", "demo_crowd_min", "demo_crowd_max", "demo_pre_curl",
                          # the actor's Q-filtered behaviour-cloning term on them (DDPGfD), and its filter
                          "demo_bc", "demo_until_step", "demo_bc_return_filter",
                          # what the demonstrations read and where they stop the wheels
                          "demo_told_zones", "demo_end_zone_stop", "demo_push_curl", "demo_late_lift",
                          # which episodes are demonstrations beyond demo_share: those told too steep, and those
                          # on the slope bins the curriculum counts failing
                          "demo_told_high", "demo_failing_share",
                          # ... and only on the bins where the teacher does at least as well as the actor
                          "demo_where_teacher_wins",
                          # the drift flags the demonstrations read (the actor's) and how long one must hold
                          "demo_drift_confirm",
                          # where the training's episode seeds start (which piles it practised on)
                          "episode_seed_offset",
                          # the critics' Huber loss (learning/ddpg.py)
                          "critic_huber",
                          # the penalty on the actor's tanh input (learning/ddpg.py)
                          "actor_preact_l2",
                          # the demonstrations' own returns as a lower bound on the critics' target (learning/ddpg.py)
                          "demo_q_lower_bound",
                          # the exploration noise after its decay, when not noise_final_scale (a late change
                          # for paired branches; noise_final_scale itself is in the hash)
                          "noise_after_decay")


def _with(cfg: dict, section: str, key: str, value) -> dict:
    return {**cfg, section: {**cfg[section], key: value}} if section in cfg else cfg


def config_hash(cfg: dict) -> str:
    """Stable short hash of a validated config (goes into exported policies), with the
    TRAINING_ONLY settings at their neutral values left out: a switched-off `randomization`
    section (actors trained before the section existed keep their hash; a randomised run's hash
    differs), task.r_success_pitch_margin_deg at 0, and the tilt penalty's keys while
    task.r_tilt_per_deg is 0; the tilt penalty's training schedule (TILT_SCHEDULE_KEYS) and
    training.twin_critics, the slope curriculum and the learning-rate decay (TRAINING_SCHEDULE_KEYS) never."""
    if "training" in cfg and any(k in cfg["training"] for k in TRAINING_SCHEDULE_KEYS):
        # how the critic learned and which piles the learner practised on, not what the actor sees
        cfg = {**cfg, "training": {k: v for k, v in cfg["training"].items() if k not in TRAINING_SCHEDULE_KEYS}}
    if "task" in cfg and any(k in cfg["task"] for k in TILT_SCHEDULE_KEYS):
        cfg = {**cfg, "task": {k: v for k, v in cfg["task"].items() if k not in TILT_SCHEDULE_KEYS}}
    if "sim" in cfg and float(cfg["sim"].get("attack_min_depth", 0.0)) == 0.0:
        # a stalled attack drive an error, as before the key (2026-11-29): the hash every file had
        cfg = {**cfg, "sim": {k: v for k, v in cfg["sim"].items() if k != "attack_min_depth"}}
    if "task" in cfg and float(cfg["task"].get("bucket_fill_factor", 0.0)) == 0.0:
        # no fill factor: the whole static heap, as before the key (SIM_CHANGES, 2026-12-02): the hash every file had
        cfg = {**cfg, "task": {k: v for k, v in cfg["task"].items() if k != "bucket_fill_factor"}}
    if "machine" in cfg and int(cfg["machine"].get("rear_differential", 0)) == 0:
        # the drive before the rear differential (SIM_CHANGES): the hash it always had
        cfg = {**cfg, "machine": {k: v for k, v in cfg["machine"].items() if k != "rear_differential"}}
    if int(cfg.get("randomization", {}).get("enabled", 0)) == 0:
        cfg = {k: v for k, v in cfg.items() if k != "randomization"}
    else:
        drop = set()
        if all(float(cfg["randomization"].get(k, 1.0)) == 1.0 for k in ACTUATOR_GAIN_KEYS):
            # actuator gains at 1 (off): the hash randomised actors had before the keys existed (2026-11-28)
            drop.update(ACTUATOR_GAIN_KEYS)
        # likewise each key added later, at the value that trains as before it existed
        drop.update(k for k, default in RANDOMIZATION_LATER_KEYS
                    if _same(cfg["randomization"].get(k, default), default))
        if drop:
            cfg = {**cfg, "randomization": {k: v for k, v in cfg["randomization"].items() if k not in drop}}
    if "task" in cfg and float(cfg["task"].get("r_success_pitch_margin_deg", 0.0)) == 0.0:
        cfg = {**cfg, "task": {k: v for k, v in cfg["task"].items() if k != "r_success_pitch_margin_deg"}}
    if "task" in cfg and float(cfg["task"].get("r_tilt_per_deg", 0.0)) == 0.0:
        cfg = {**cfg, "task": {k: v for k, v in cfg["task"].items() if k not in TILT_KEYS}}
    return hashlib.sha256(json.dumps(cfg, sort_keys=True).encode()).hexdigest()[:16]


def task_hash(cfg: dict) -> str:
    """Short hash of the whole `task` section, shaping keys included (those config_hash leaves out: the tilt
    schedule, midgoal_from_pile, reward_zones_from_pile, ...). Two processes that compute one run's rewards (a
    learner and the sim nodes it trains from) must agree on it as well as on config_hash: the reward is not part
    of what the actor sees, but it is what the card records the actor was trained with."""
    return hashlib.sha256(json.dumps(cfg.get("task", {}), sort_keys=True).encode()).hexdigest()[:16]


def training_variants(cfg: dict, trained_margin_deg: float | None = None,
                      trained_tilt: tuple[float, float] | None = None) -> list[dict]:
    """`cfg` with its TRAINING_ONLY settings at every value an actor that runs on it may have
    been trained with: randomisation on or off (this config's ranges), r_success's pitch
    margin at 0 (actors trained before it existed), at this config's value, or at
    `trained_margin_deg` (the card's `trained_with`), the tilt penalty off, at this
    config's (r_tilt_per_deg, r_tilt_free_deg) or at `trained_tilt` (the card's), and, randomised,
    a slope-estimate error in the observed alpha only or also in the zones
    (randomization.zones_from_slope_estimate 0 or this config's), no start from rest or this
    config's share of them (randomization.rest_start_share 0 or this config's), and plane piles or this
    config's relief (randomization.surface_sd_max 0 or this config's), and the pile's own zones or the
    end-zone node's at the nominal density (randomization.zones_at_nominal_density 0 or this config's), and true arm
    angles or this config's angle-sensor offsets (randomization.arm_offset_max_deg 0 or this config's), and the
    slope error drawn alike in every episode or this config's share told too steep
    (randomization.slope_error_high_share 0 or this config's). Every other range of
    the randomisation section is part of a randomised actor's identity: such an actor runs on its own
    parameter file (lhd ship copies it)."""
    rands = [0, 1] if "randomization" in cfg else [None]
    task = cfg.get("task", {})
    margins = {0.0, float(task.get("r_success_pitch_margin_deg", 0.0))}
    if trained_margin_deg is not None:
        margins.add(float(trained_margin_deg))
    tilts = {(0.0, 0.0), (float(task.get("r_tilt_per_deg", 0.0)), float(task.get("r_tilt_free_deg", 0.0)))}
    if trained_tilt is not None:
        tilts.add((float(trained_tilt[0]), float(trained_tilt[1])))
    r_cfg = cfg.get("randomization", {})
    # each key added later: as before it existed, or this config's value (RANDOMIZATION_LATER_KEYS)
    later = [(k, sorted({default, type(default)(r_cfg.get(k, default))})) for k, default in RANDOMIZATION_LATER_KEYS]
    out = []
    cs = []
    for rand in rands:
        c = cfg if rand is None else _with(cfg, "randomization", "enabled", rand)
        if rand != 1:
            cs.append(c)
            continue
        # randomised: where a slope-estimate error went while it trained (alpha alone before 2026-11-28), whether
        # some episodes started from rest, whether piles were rough (neither before 2026-11-29), ...
        for values in itertools.product(*(v for _, v in later)):
            cv = c
            for (k, _), v in zip(later, values):
                cv = _with(cv, "randomization", k, v)
            cs.append(cv)
    for c in cs:
        for m in sorted(margins):
            cm = _with(c, "task", "r_success_pitch_margin_deg", m)
            for per_deg, free in sorted(tilts):
                out.append(_with(_with(cm, "task", "r_tilt_per_deg", per_deg), "task", "r_tilt_free_deg", free))
    return out


def hash_matches(h: str | None, cfg: dict, trained_margin_deg: float | None = None,
                 trained_tilt: tuple[float, float] | None = None) -> bool:
    """Whether an actor card's config hash `h` names this config up to its TRAINING_ONLY settings
    (training_variants): trained on it as it is, with its domain randomisation switched on or off
    (`lhd train --randomize` with this `randomization` section), and/or with r_success's pitch
    margin at 0, at this config's or at the card's value. These change what the actor was trained
    on, not what it sees or commands, so the nodes may run it."""
    if not h:
        return False
    return any(h == config_hash(c) for c in training_variants(cfg, trained_margin_deg, trained_tilt))


# Keys added to the SIMULATOR's physics after actors were exported: (section, keys, date, what the simulator did
# before). They do not change what an actor sees or commands (observation, normalisers, actions, filters), so an
# actor trained before they existed still runs on this config; its card's hash is this config's with the keys
# removed. `sim_change_note` recognises it and says so, instead of the "another parameter file" warning.
SIM_CHANGES = (
    ("pile", ("fee_wedge_by_motion", "fee_wedge_tau"), "2026-11-26",
     "the lip's FEE wedge resisted any horizontal tip motion, also lifting and curling out of the face"),
    ("machine", ("rear_differential",), "2026-11-26",
     "each rear wheel had its own motor; the paper's machine drives them through one motor and a differential"),
    ("task", ("bucket_fill_factor",), "2026-12-02",
     "the bucket held its whole geometric capacity, a heap at the static angle of repose: 1.10 of its SAE rating "
     "at a 40 deg curl, where loaders deliver 0.85-0.90 of it in coarse gravel"),
)


def older_configs(cfg: dict) -> list[tuple[dict, list[str]]]:
    """`cfg` as it was before the newest k simulator changes of SIM_CHANGES (k = 1, 2, ...; the
    list is in date order), each with the changes undone, newest first described: what an actor
    trained between two changes had as its config."""
    out, older, done = [], cfg, []
    for section, keys, date, before in reversed(SIM_CHANGES):
        if section not in older or not any(k in older[section] for k in keys):
            continue
        undone = {**older, section: {k: v for k, v in older[section].items() if k not in keys}}
        if config_hash(undone) == config_hash(older):
            continue      # the key at the value meaning "as before" (rear_differential: 0): no change to name
        older = undone
        done = [f"{section}.{'/'.join(keys)} ({date}; before: {before})"] + done
        out.append((older, list(done)))
    return out


def sim_change_note(h: str | None, cfg: dict, trained_margin_deg: float | None = None,
                    trained_tilt: tuple[float, float] | None = None) -> str | None:
    """Why a card's hash `h` that does not name `cfg` (hash_matches) is still this config: it names
    `cfg` as it was before the latest simulator changes of SIM_CHANGES (older_configs), i.e. the
    actor was trained on the simulator before them. None otherwise."""
    if not h or hash_matches(h, cfg, trained_margin_deg, trained_tilt):
        return None
    for older, done in older_configs(cfg):
        if hash_matches(h, older, trained_margin_deg, trained_tilt):
            return ("trained on the simulator before " + "; ".join(done) +
                    ": the observation, actions and ranges are this config's; its card's evaluation says how it does now")
    return None


def trained_randomized(h: str | None, cfg: dict, trained_margin_deg: float | None = None) -> bool:
    """Whether `h` names this config with domain randomisation switched on (and not also with it
    off: the two hashes differ whenever the section exists)."""
    if not h or "randomization" not in cfg:
        return False
    for c in [cfg] + [older for older, _ in older_configs(cfg)]:   # also before later simulator changes
        variants = training_variants(c, trained_margin_deg)
        on = {config_hash(v) for v in variants if int(v["randomization"]["enabled"]) == 1}
        off = {config_hash(v) for v in variants if int(v["randomization"]["enabled"]) == 0}
        if h in on and h not in off:
            return True
    return False
