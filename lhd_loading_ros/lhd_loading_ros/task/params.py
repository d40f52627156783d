"""Flat, typed view of the validated config used by the task math (angles in radians)."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from lhd_loading_ros.task.zones import derived_normalisers


@dataclass(frozen=True)
class TaskParams:
    # reward constants (paper table)
    R_zone: float
    R_traj: float
    R_drift: float
    R_bottom: float
    R_midgoal: float
    d_midgoal_max: float
    R_stuck: float
    T_stuck: int
    delta_thresh: float
    R_inact: float
    u_thresh_boom: float
    u_thresh_bucket: float
    R_weight: float
    R_dump: float
    phi_thresh_pitch: float
    R_success: float
    W_target: float
    phi_target: float
    rho_thresh_W: float
    rho_thresh_phi: float
    # observation
    d_end_max: float
    x_init_obs: float
    x_obs: float
    y_obs: float
    z_obs: float
    # control
    control_dt: float
    wheels_min: float
    wheels_max: float
    boom_min: float
    boom_max: float
    bucket_min: float
    bucket_max: float
    # zones / pile
    m_min: float
    m_max: float
    z_min: float
    h_pile: float
    w_pile: float
    alpha_min: float
    alpha_max: float
    d_init: float
    max_steps: int
    # task choices
    bucket_capacity: float
    loaded_fraction: float
    d_cutoff: float
    x_midgoal: float
    x_delta: float
    x_offset: float
    z_offset: float
    rail_exponent: int
    v_x_max: float
    boom_angle_min: float
    boom_angle_max: float
    bucket_angle_min: float
    bucket_angle_max: float
    phi_shovel_min: float
    phi_shovel_max: float
    drift_slip_ratio: float
    drift_min_speed: float
    rlc_boom_saturate: float
    rlc_bucket_saturate: float
    rld_threshold: float
    r_dump_sign: int
    r_weight_increments: int
    r_success_requires_sl: int
    bottom_tolerance: float
    bucket_repose: float = math.radians(35.0)   # angle of repose of the material (bucket capacity)
    normalisers_from_pile: int = 0              # 1: d_end_max / x_obs derived from the pile family (zones.py)
    r_success_pitch_margin: float = 0.0         # rad; r_success only when phi^T > phi_thresh_pitch + this (training)
    r_success_mass_margin: float = 0.0          # kg; r_success only when W^T >= the success test's 20 kg + this (training)
    r_tilt_per_deg: float = 0.0                 # training: r_tilt = -this x (|machine pitch| - r_tilt_free) per step, deg
    r_tilt_free: float = 0.0                    # rad; a machine pitch this small costs nothing
    midgoal_from_pile: int = 0                  # 1: r_midgoal / r_inact switch at the episode pile's x_min (for_pile)
    reward_zones_from_pile: int = 0             # 1: the reward's terms read the pile's own zones, not the told ones (training)

    def for_pile(self, zones) -> "TaskParams":
        """These parameters for one episode's pile: with midgoal_from_pile, x_midgoal is the end zone's
        x_min (where the intact pile holds m_min between its toe and x; the paper's 0.54 m is that of a
        30 deg pile, 0.53-0.57 m over the gravel densities) and d_midgoal_max = x_midgoal - d_init, the
        largest d_midgoal, as the paper's 0.44 m is for 0.54 m. Otherwise self (the paper's constants)."""
        if not self.midgoal_from_pile:
            return self
        return replace(self, x_midgoal=zones.x_min, d_midgoal_max=max(zones.x_min - self.d_init, 1e-3))

    @classmethod
    def from_config(cls, cfg: dict) -> "TaskParams":
        p, t = cfg["paper"], cfg["task"]
        r, o, c, e, z = p["reward"], p["observation"], p["control"], p["episode"], p["end_zone"]
        rad = math.radians
        # d_end_max and x_obs: the paper's table, or derived from the pile family (docs/modeling.md)
        d_end_max, x_obs = derived_normalisers(cfg) if t["normalisers_from_pile"] else (o["d_end_max"], o["x_obs"])
        return cls(
            R_zone=r["R_zone"], R_traj=r["R_traj"], R_drift=r["R_drift"], R_bottom=r["R_bottom"],
            R_midgoal=r["R_midgoal"], d_midgoal_max=r["d_midgoal_max"], R_stuck=r["R_stuck"],
            T_stuck=r["T_stuck"], delta_thresh=r["delta_thresh"], R_inact=r["R_inact"],
            u_thresh_boom=r["u_thresh_boom"], u_thresh_bucket=r["u_thresh_bucket"], R_weight=r["R_weight"],
            R_dump=r["R_dump"], phi_thresh_pitch=rad(r["phi_thresh_pitch_deg"]), R_success=r["R_success"],
            W_target=r["W_target"], phi_target=rad(r["phi_target_deg"] + t["success_pitch_margin_deg"]), rho_thresh_W=r["rho_thresh_W"],
            rho_thresh_phi=rad(r["rho_thresh_phi_deg"]),
            d_end_max=d_end_max, x_init_obs=o["x_init_obs"], x_obs=x_obs, y_obs=o["y_obs"], z_obs=o["z_obs"],
            control_dt=1.0 / c["frequency_hz"], wheels_min=c["wheels_min"], wheels_max=c["wheels_max"],
            boom_min=c["boom_min"], boom_max=c["boom_max"], bucket_min=c["bucket_min"], bucket_max=c["bucket_max"],
            m_min=z["m_min"], m_max=z["m_max"], z_min=z["z_min"], h_pile=e["h_pile"], w_pile=e["w_pile"],
            alpha_min=rad(e["alpha_min_deg"]), alpha_max=rad(e["alpha_max_deg"]), d_init=e["d_init"],
            max_steps=e["max_steps"],
            bucket_capacity=t["bucket_capacity"], loaded_fraction=t["loaded_fraction"], d_cutoff=t["d_cutoff"],
            x_midgoal=t["x_midgoal"], x_delta=t["x_delta"], x_offset=t["x_offset"], z_offset=t["z_offset"],
            rail_exponent=t["rail_exponent"], v_x_max=t["v_x_max"], boom_angle_min=t["boom_angle_min"],
            boom_angle_max=t["boom_angle_max"], bucket_angle_min=t["bucket_angle_min"],
            bucket_angle_max=t["bucket_angle_max"], phi_shovel_min=rad(t["phi_shovel_min_deg"]),
            phi_shovel_max=rad(t["phi_shovel_max_deg"]), drift_slip_ratio=t["drift_slip_ratio"],
            drift_min_speed=t["drift_min_speed"], rlc_boom_saturate=t["rlc_boom_saturate"],
            rlc_bucket_saturate=t["rlc_bucket_saturate"], rld_threshold=t["rld_threshold"], r_dump_sign=t["r_dump_sign"], r_weight_increments=t["r_weight_increments"],
            r_success_requires_sl=t["r_success_requires_sl"],
            r_success_pitch_margin=rad(t.get("r_success_pitch_margin_deg", 0.0)),
            r_success_mass_margin=float(t.get("r_success_mass_margin_kg", 0.0)), bottom_tolerance=t["bottom_tolerance"],
            r_tilt_per_deg=t.get("r_tilt_per_deg", 0.0), r_tilt_free=rad(t.get("r_tilt_free_deg", 0.0)),
            bucket_repose=rad(t["bucket_repose_deg"]), normalisers_from_pile=t["normalisers_from_pile"],
            midgoal_from_pile=int(t.get("midgoal_from_pile", 0)),
            reward_zones_from_pile=int(t.get("reward_zones_from_pile", 0)),
        )
