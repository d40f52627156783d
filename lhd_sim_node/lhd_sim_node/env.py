"""Gymnasium environment ``LhdLoading-v0``: the paper's loading POMDP on the MuJoCo simulator.

Observation: the 12-vector of lhd_loading_ros.task.observation. Action: [-1, 1]^3
(wheels, boom, bucket). variant="rld" passes boom and bucket through the hybrid filter
(threshold 0) before they reach the machine; variant="rlc" keeps them continuous
(deploy_filter=True adds the RLC deployment filter, as on the real machine).
randomize=True (default: the config's randomization.enabled) draws each episode's conditions
(task/randomization.py: slope-estimate error, sensor noise, dropouts and delays, actuator dead
time, material, tyre friction, start pose); reset(options={"conditions": Conditions(...)}) sets
them instead. The reward and the episode's outcome use the true state of the machine and the
pile; the observation carries the sensor errors. A slope-estimate error (conditions.slope_error_deg,
and a rough face's scanned slice) also moves the zones when zones_from_estimate is on (default: the
config's randomization.zones_from_slope_estimate): on the machine the end-zone node builds them from
the LiDAR's slope, so the observed d_end, the end zone and the restricted zone that end the episode
(the supervisor's) are the estimate's (task/zones.zones_for_slope_estimate); the pile is the true one.
zones_nominal_density (default: the config's randomization.zones_at_nominal_density, where the section is
on) builds them as the end-zone node does, at the config's nominal bulk density, blind to the pile's own
density and rocks (task/end_zone.zones_at_nominal_density).
An episode ends with success (bucket tip in the end zone), failure (restricted zone), or
truncation after max_steps (200) control steps, which is not a terminal state.
"""
from __future__ import annotations

import math
import numbers
import time
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np

from lhd_loading_ros.policy.core import slope_refusal
from lhd_loading_ros.task.actions import apply_variant_filter, to_actuator, validate_action
from lhd_loading_ros.task.arm_sensors import RATE_WINDOW_S, RateWindow, quantize
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.end_zone import density_problem, nominal_density, zones_at_nominal_density
from lhd_loading_ros.task.kinematics import ArmKinematics, quat_to_mat
from lhd_loading_ros.task.metrics import EpisodeResult, drift_pct, success_level
from lhd_loading_ros.task.observation import OBS_HIGH, OBS_LOW, build_observation
from lhd_loading_ros.task.randomization import NOMINAL, Conditions, ObservationCorruptor, RandomizationRanges, draw
from lhd_loading_ros.task.reward import RewardTracker
from lhd_loading_ros.task.zones import classify, zones_for_slope_estimate

from .simulator import MATERIALS, AttackError, LhdSimulator, SimulationError

VARIANTS = ("rld", "rlc")
ATTACK_REDRAWS = 5          # a stalled attack drive: the pile drawn again at most this often (reset, reset_or_redraw)
D_ATTACK_LIMIT_M = 1.0     # m: the farthest start the reset option d_attack takes (the attack timeout's reach)
RESET_OPTIONS = frozenset(("slope_deg", "material", "conditions", "d_attack", "attack_speed"))



def drift_lag_chunks(rng: np.random.Generator, lag_max_s: float, chunk_s: float, prev: int | None,
                     period_s: float) -> int:
    """The lag of one observation's drift window, in chunks of the simulator's FEE step: U{0..lag_max_s / chunk_s},
    one integer drawn from `rng`, capped so that the window ends no earlier than the previous observation's did
    (`prev`, that lag in chunks, None at the first observation), one control period `period_s` before: the bridge's
    window ends at its newest camera image, and a newer image is never older than one it has used."""
    n = int(round(lag_max_s / chunk_s))
    if n < 0:
        raise ValueError(f"lag_max_s {lag_max_s!r}: expected >= 0 s")
    lag = int(rng.integers(0, n + 1))
    if prev is not None:
        lag = min(lag, prev + int(round(period_s / chunk_s)))
    return lag

class LhdLoadingEnv(gym.Env):
    metadata = {"render_modes": [], "render_fps": 10}

    def __init__(self, variant: str = "rld", config: dict | str | None = None, slope_deg: float | None = None,
                 material: str | None = None, deploy_filter: bool = False, randomize: bool | None = None,
                 zones_from_estimate: bool | None = None, zones_nominal_density: bool | None = None,
                 zones_density: float | None = None, attack_redraws: int | None = None, render_mode: str | None = None):
        if render_mode is not None:
            raise ValueError(f"render_mode = {render_mode!r}: this environment renders nothing (metadata render_modes "
                             "is empty); `lhd replay BAG --video` animates a recorded attempt, and mujoco.viewer can "
                             "show env.unwrapped.sim.model / .data")
        self.render_mode = None
        self._closed = False
        if variant not in VARIANTS:
            raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
        # flags are booleans: a string such as "no" or "false" was taken as true (an RL-API review, 2026-11-29)
        for name, v, optional in (("deploy_filter", deploy_filter, False), ("randomize", randomize, True),
                                  ("zones_from_estimate", zones_from_estimate, True),
                                  ("zones_nominal_density", zones_nominal_density, True)):
            if not (isinstance(v, (bool, np.bool_)) or (optional and v is None)):
                raise ValueError(f"{name} = {v!r}: expected True or False" + (" (or None: the config's)" if optional else ""))
        if deploy_filter and variant != "rlc":
            raise ValueError("deploy_filter=True is the RLC deployment filter (docs/training.md); the rld variant "
                             "has no such filter: expected deploy_filter=False with variant 'rld'")
        if attack_redraws is None:
            attack_redraws = ATTACK_REDRAWS
        if isinstance(attack_redraws, bool) or not isinstance(attack_redraws, numbers.Integral) or attack_redraws < 0:
            raise ValueError(f"attack_redraws = {attack_redraws!r}: expected an integer >= 0")
        # reset() draws the pile and conditions again, from the env's own random stream, where the attack drive
        # cannot bury the bucket (AttackError: about 1 reset in 80 on 35 deg piles under the wide files'
        # randomisation) or MuJoCo finds it unstable: a Gym loop, or a vector env's autoreset inside step(), must
        # not die on it (a review). 0: raise at once (reset_or_redraw sets it so: its own redraws are seeded)
        self.attack_redraws = int(attack_redraws)
        self.attack_redraws_used = 0
        if material is not None and material not in MATERIALS:
            raise ValueError(f"material must be one of {MATERIALS} or None (random), got {material!r}")
        self.cfg = config if isinstance(config, dict) else load_config(config)
        self.sim = LhdSimulator(self.cfg)
        self.p = self.sim.p
        self._kin = ArmKinematics.from_config(self.cfg)
        self._check_slope(slope_deg, "slope_deg")
        self.variant = variant
        self.slope_deg = slope_deg
        self.material = material
        self.deploy_filter = deploy_filter
        self.ranges = RandomizationRanges.from_config(self.cfg)
        self.randomize = self.ranges.enabled if randomize is None else bool(randomize)
        self.zones_from_estimate = (self.ranges.zones_from_slope_estimate if zones_from_estimate is None
                                    else bool(zones_from_estimate))
        # the zones as the end-zone node builds them: a wedge at the nominal bulk density, blind to the
        # pile's own density and rocks (task/end_zone.zones_at_nominal_density). From the config only where
        # the randomisation section is on (the config hash carries the key then only), so that a parameter
        # file shipped with the section off judges by the pile's zones whatever the key says
        self.zones_nominal_density = ((self.ranges.enabled and self.ranges.zones_at_nominal_density)
                                      if zones_nominal_density is None else bool(zones_nominal_density))
        # the end-zone node's `density` parameter: None (its default 0) takes the config's nominal density
        if zones_density is not None and density_problem(zones_density):
            raise ValueError(f"zones_density: {density_problem(zones_density)}")
        self.rho_nominal = nominal_density(self.cfg) if zones_density is None else float(zones_density)
        self.zones = None
        self.zones_from = "pile"
        self.told_slope_deg, self.slope_refusal = None, ""     # set at reset
        self.conditions = NOMINAL
        self._lag_rng = None                  # the bridge's drift-window lag (reset)
        self.observation_space = gym.spaces.Box(OBS_LOW, OBS_HIGH, dtype=np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self._done = True

    def _check_slope(self, slope_deg, name: str) -> None:
        """A pile slope outside the configured range (paper.episode alpha_min_deg..alpha_max_deg,
        the range the actors are trained on) is refused, never clipped: a pile the actors never
        saw must not be reported as if it were one they did."""
        if slope_deg is None:
            return
        lo, hi = math.degrees(self.p.alpha_min), math.degrees(self.p.alpha_max)
        # any real number (numpy's float32 / int64 too; a review found them refused with an untrue message), not a bool
        ok = isinstance(slope_deg, numbers.Real) and not isinstance(slope_deg, (bool, np.bool_))
        if not (ok and math.isfinite(slope_deg) and lo - 1e-9 <= slope_deg <= hi + 1e-9):
            raise ValueError(f"{name} = {slope_deg!r} degrees is outside the configured pile range [{lo:g}, {hi:g}] "
                             "degrees (paper.episode.alpha_min_deg / alpha_max_deg); expected a slope in it")

    # ------------------------------------------------------------------ gym API
    def _check_attack(self, options: dict) -> None:
        """The reset options d_attack (m, the tip's distance before the toe when the drive in starts) and
        attack_speed (rad/s of the wheels during it): finite, within what the attack drive can do."""
        d = options.get("d_attack")
        if d is not None and not (isinstance(d, numbers.Real) and math.isfinite(d) and 0.0 < d <= D_ATTACK_LIMIT_M):
            raise ValueError(f"options['d_attack'] = {d!r}: expected metres in (0, {D_ATTACK_LIMIT_M:g}] (the config's "
                             "paper.episode.d_attack_min..d_attack_max is what training draws)")
        s = options.get("attack_speed")
        if s is not None and not (isinstance(s, numbers.Real) and math.isfinite(s) and 0.0 < s <= self.p.wheels_max):
            raise ValueError(f"options['attack_speed'] = {s!r}: expected a wheel speed in (0, {self.p.wheels_max:g}] "
                             "rad/s (control.wheels_max)")

    def close(self) -> None:
        """No more episodes: step() and reset() refuse afterwards (the simulator's memory goes with the env)."""
        self._done = True
        self._closed = True

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if self._closed:
            raise RuntimeError("reset() on a closed environment: create a new one")
        super().reset(seed=seed)
        # until this reset has built its episode, no step: a reset that raises must not leave the previous
        # episode steppable on a half-built pile (a review stored such a transition)
        self._done = True
        options = options or {}
        unknown = sorted(set(options) - RESET_OPTIONS)
        if unknown:       # a misspelt option would otherwise be dropped without a word (a review)
            import difflib

            hints = [f"{k!r} (did you mean {near[0]!r}?)" if (near := difflib.get_close_matches(k, RESET_OPTIONS, n=1))
                     else repr(k) for k in unknown]
            raise ValueError(f"unknown reset option {', '.join(hints)}; expected some of {', '.join(sorted(RESET_OPTIONS))}")
        slope = options.get("slope_deg", self.slope_deg)
        self._check_slope(slope, "options['slope_deg']")
        alpha = None if slope is None else math.radians(slope)
        given = options.get("conditions")
        if given is not None and not isinstance(given, Conditions):
            raise ValueError(f"options['conditions'] must be a task.randomization.Conditions, got {type(given).__name__}")
        self._check_attack(options)
        first_error = None
        for redraw in range(self.attack_redraws + 1):
            c = given if given is not None else (draw(self.np_random, self.ranges) if self.randomize else NOMINAL)
            arm_rates = self._arm_rate_windows(c)      # refused before anything of the episode is set
            self.conditions = c
            try:
                self.sim.reset(self.np_random, alpha=alpha, material=options.get("material", self.material),
                               d_attack=options.get("d_attack"), attack_speed=options.get("attack_speed"), conditions=c)
                break
            except (AttackError, SimulationError) as exc:
                first_error = first_error or exc
        else:
            raise first_error
        self.attack_redraws_used = redraw
        c_obs = c
        if c.surface_sd > 0.0:
            # a rough face: the LiDAR scans one slice of it (the pile's XZ plane), whose own slope
            # differs from the plane's; that difference is part of the slope the policy is told
            slice_err = math.degrees(self.sim.pile.slice_slope(0.0) - self.sim.pile.alpha)
            c_obs = replace(c, slope_error_deg=c.slope_error_deg + slice_err)
        self._sensors = None if c_obs == NOMINAL else ObservationCorruptor(c_obs, self.np_random)
        # the slope the controller is told (the LiDAR's: the pile's, its error, a rough face's slice), and
        # whether the policy node would refuse it (outside the range the actors are trained on): on the
        # machine such an attempt does not run. Training runs it with the observation clipped; an
        # evaluation counts it as refused (learning/evaluate.run_policy_episode, refused_result)
        self.told_slope_deg = math.degrees(self.sim.pile.alpha) + c_obs.slope_error_deg
        self.slope_refusal = slope_refusal(math.radians(self.told_slope_deg),
                                           (math.degrees(self.p.alpha_min), math.degrees(self.p.alpha_max)))
        self.zones, self.zones_from = self._task_zones(c_obs)
        s = self.sim.state()
        # the zones the reward reads: those the episode is observed and ended with, or (task.reward_zones_from_pile, a
        # training setting) the pile's own, where a slope told wrong (or the nominal density) moves the told ones:
        # the rail, and with task.midgoal_from_pile the mid goal and r_inact, then shape the maneuver that suits the
        # pile in front of the machine, while the observation, the end of the episode and so when r_success is paid
        # stay with the told zones, as on the machine
        self.reward_zones = self.sim.zones if self.p.reward_zones_from_pile else self.zones
        # the reward's x_midgoal: the paper's constant, or this pile's x_min (task.midgoal_from_pile)
        self.tracker = RewardTracker(self.p.for_pile(self.reward_zones), self.reward_zones, self.p.h_pile)
        self.tracker.reset(s, self.sim.loaded_mass)
        self.steps = 0
        self.ret = 0.0
        self._front, self._rear = [], []
        self._max_tilt = abs(self.sim.machine_pitch())
        self._done = False
        self._state = s
        self._arm_rates = arm_rates
        # the bridge's drift window (conditions.drift_flag_lag_max_s): its lag drawn from a stream of its own, a jump
        # ahead of the episode's generator, which it leaves as it is: the sensor noise of an episode is the same with
        # and without it (`--stress machine` against `machine_bridge` are paired)
        self._lag_rng = (np.random.Generator(self.np_random.bit_generator.jumped())
                         if c.drift_flag_lag_max_s > 0.0 else None)
        self._lag_prev = None                 # the last observation's lag in chunks (its window's end never goes back)
        self._m = self._measured(s)
        info = self._info(s, "running", {})
        info["told_slope_deg"], info["slope_refusal"] = self.told_slope_deg, self.slope_refusal
        info["attack_redraws"] = self.attack_redraws_used
        info["attack_stalled"] = bool(self.sim.attack_stalled)   # started short of d_init (sim.attack_min_depth)
        return self._obs(self._m), info

    def step(self, action):
        if self._done:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        a = validate_action(action)
        a = apply_variant_filter(a, self.variant, self.p, deploy=self.deploy_filter)
        return self.step_actuator(to_actuator(a, self.p))

    def step_actuator(self, u):
        """One control period with actuator commands u = (u_wheels, u_boom, u_bucket) in rad/s,
        already filtered (what /lhd/cmd carries; the sim node steps through here). Returns
        what step() returns."""
        if self._done:
            raise RuntimeError("step_actuator() called on a finished episode; call reset() first")
        u = np.asarray(u, dtype=np.float64)
        if u.shape != (3,) or not np.isfinite(u).all():
            raise ValueError(f"actuator command must be 3 finite values (u_wheels, u_boom, u_bucket) rad/s, got {u}")
        self.sim.step(u)
        s = self.sim.state()
        self.steps += 1
        m = self._m = self._measured(s)   # the supervisor ends the attempt on the tip its sensors give
        zone = classify(m.x_shovel, m.y_shovel, m.z_shovel, self.zones)
        outcome = {"end": "success", "restricted": "failure"}.get(zone, "running")
        pile = self.sim.pile
        inside = 0.0 <= s.x_shovel < pile.L and s.z_shovel < pile.surface_height(s.x_shovel)
        W = self.sim.loaded_mass
        tilt = self.sim.machine_pitch()
        terms = self.tracker.step(s, u[1], u[2], W, inside, pile.surface_height(s.x_bottom), outcome, tilt)
        r = float(sum(terms.values()))
        self.ret += r
        self._front.append(s.drift_front)
        self._rear.append(s.drift_rear)
        self._max_tilt = max(self._max_tilt, abs(tilt))   # at the control period's end
        terminated = outcome != "running"
        truncated = (not terminated) and self.steps >= self.p.max_steps
        self._done = terminated or truncated
        self._state = s
        info = self._info(s, outcome, terms, u)
        info["success_margin_cut"] = self.tracker.margin_cut   # in terms["success"]; apart for a ramped margin
        if self._done:
            info["episode_result"] = self.result(outcome, truncated)
        return self._obs(m), r, terminated, truncated, info

    # ------------------------------------------------------------------ helpers
    def _task_zones(self, c_obs: Conditions):
        """The zones the episode is observed and ended with, and where they come from: the pile's
        own, or (zones_from_estimate, a slope-estimate error) those the end-zone node builds from
        the estimate. An estimate outside the LiDAR's physical range gets none on the machine (the
        attempt would not start); here the pile's own zones stand in ("pile, estimate out of range").
        With zones_nominal_density the end-zone node's wedge at the config's nominal density is built
        from the estimate (or, without zones_from_estimate, from the true slope), whatever the pile's
        density and rocks ("wedge at nominal density")."""
        zones = self.sim.zones
        alpha = self.sim.pile.alpha
        if self.zones_nominal_density:
            est = alpha + (math.radians(c_obs.slope_error_deg) if self.zones_from_estimate else 0.0)
            try:
                return zones_at_nominal_density(est, self.rho_nominal, self.p), "wedge at nominal density"
            except ValueError:       # outside the LiDAR's range, or a wedge too steep to hold m_max
                return zones, "pile, the end-zone node publishes none for the estimate"
        if not self.zones_from_estimate or c_obs.slope_error_deg == 0.0:
            return zones, "pile"
        try:
            return zones_for_slope_estimate(zones, alpha, alpha + math.radians(c_obs.slope_error_deg), self.p), \
                "estimate"
        except ValueError:
            return zones, "pile, estimate out of range"

    def _measured(self, s):
        """The state as the machine's sensors give it (_arm_measured), with the drift flags the bridge gives where the
        episode's conditions lag its window (drift_flag_lag_max_s: over a control period ending U{0..lag_max} chunks
        before now, drawn each step, but never ending before the last observation's window ended: the bridge's window
        ends at its newest camera image, and images arrive in order, so on the machine that end never goes back;
        drawn freely it would in about 5 % of the step pairs at 0.14 s; LhdSimulator.drift_flag): the observation and
        the scripted controllers of `lhd experiment paper` (env.measured_state) read them; the reward, the episode's
        drift figures and the training's demonstrations (the true state) keep the simulator's own window."""
        m = self._arm_measured(s)
        if self._lag_rng is None:
            return m
        lag = drift_lag_chunks(self._lag_rng, self.conditions.drift_flag_lag_max_s, self.sim.fee_dt,
                               self._lag_prev, self.p.control_dt)
        self._lag_prev = lag
        front, rear = self.sim.drift_flag(lag)
        return replace(m, drift=front or rear, drift_front=front, drift_rear=rear)

    def _arm_measured(self, s):
        """The state as the machine's arm sensors give it: with the arm's angle sensors zeroed off the attack pose
        (conditions.boom_offset_deg, bucket_offset_deg) and, where the episode samples them (conditions.arm_angle_noise_deg,
        arm_encoder_counts: _arm_rates), read with noise and in counts, the rates then the firmware's differences of the
        samples over its rate window (task/arm_sensors.py; the window is the control period, so the sample one step back);
        the tip and its pitch where the arm's kinematics (task/kinematics.py, as the policy node and the supervisor compute
        them) puts them at the measured angles. Without any of these, s. Called once a step (it draws the noise and keeps
        the samples): env.measured_state is the step's."""
        c = self.conditions
        db, dk = math.radians(c.boom_offset_deg), math.radians(c.bucket_offset_deg)
        if self._arm_rates is None:
            return s if db == 0.0 and dk == 0.0 else self._at_arm_angles(s, s.phi_boom + db, s.phi_bucket + dk)
        sd = math.radians(c.arm_angle_noise_deg)
        t = self.steps * self.p.control_dt
        angles, rates = [], []
        for true, off, window in ((s.phi_boom, db, self._arm_rates[0]), (s.phi_bucket, dk, self._arm_rates[1])):
            a = quantize(true + off + (float(self.np_random.normal(0.0, sd)) if sd > 0.0 else 0.0), c.arm_encoder_counts)
            angles.append(a)
            rates.append(window.push(t, a))
        return replace(self._at_arm_angles(s, *angles), dphi_boom=rates[0], dphi_bucket=rates[1])

    def _arm_rate_windows(self, c: Conditions):
        """The boom's and bucket's RateWindow where the conditions sample the arm's angles, else None."""
        noise, counts = c.arm_angle_noise_deg, c.arm_encoder_counts
        if noise == 0.0 and counts == 0:
            return None
        whole = isinstance(counts, numbers.Integral) and not isinstance(counts, bool)
        if not (math.isfinite(noise) and 0.0 <= noise <= 5.0) or not (whole and counts >= 0):
            raise ValueError(f"conditions: arm_angle_noise_deg {noise!r} must be a sd in [0, 5] deg and arm_encoder_counts "
                             f"{counts!r} a whole number of counts per turn >= 0 (0: exact)")
        if abs(RATE_WINDOW_S - self.p.control_dt) > 1e-9:
            raise ValueError(f"the firmware's rate window {RATE_WINDOW_S:g} s is not the control period "
                             f"{self.p.control_dt:g} s: the environment samples the arm once a period and cannot model it")
        return RateWindow(RATE_WINDOW_S), RateWindow(RATE_WINDOW_S)

    def _at_arm_angles(self, s, boom: float, bucket: float):
        """s with the arm read at these angles: the tip, its pitch and the bucket's bottom moved by the difference the
        angles make from the true ones at the machine's true pose."""
        q = self.sim.data.qpos
        R = quat_to_mat(*q[3:7])
        tip0, pitch0, bottom0 = self._kin.tip_and_bottom(q[0:3], R, s.phi_boom, s.phi_bucket)
        tip1, pitch1, bottom1 = self._kin.tip_and_bottom(q[0:3], R, boom, bucket)
        d, e = tip1 - tip0, bottom1 - bottom0
        return replace(s, x_shovel=s.x_shovel + float(d[0]), y_shovel=s.y_shovel + float(d[1]),
                       z_shovel=s.z_shovel + float(d[2]), phi_shovel=s.phi_shovel + math.remainder(pitch1 - pitch0, math.tau),
                       phi_boom=boom, phi_bucket=bucket,
                       x_bottom=s.x_bottom + float(e[0]), z_bottom=s.z_bottom + float(e[2]))

    def _obs(self, s):
        """The observation of the measured state s (_measured: computed once a step, for this and the end test)."""
        alpha = self.sim.pile.alpha
        if self._sensors is not None:        # what the camera and the LiDAR tell the policy
            v_x, alpha = self._sensors.observe(s.v_x, alpha)
            s = replace(s, v_x=v_x)
        return build_observation(s, alpha, self.zones.x_max, self.p)

    def _info(self, s, outcome: str, terms: dict, u=None) -> dict[str, Any]:
        return {
            "outcome": outcome, "terms": terms, "loaded_mass": self.sim.loaded_mass,
            "spilled_mass": self.sim.spilled_mass,  # kg loaded beyond the bucket's capacity and spilled
            "alpha_deg": math.degrees(self.sim.pile.alpha), "material": self.sim.material,
            "x_min": self.zones.x_min, "x_max": self.zones.x_max, "zones_from": self.zones_from,
            "drift_front": s.drift_front, "drift_rear": s.drift_rear,
            "command": None if u is None else u.tolist(),
            "conditions": self.conditions,
        }

    def result(self, outcome: str, truncated: bool) -> EpisodeResult:
        s = self._state
        W = self.sim.loaded_mass
        return EpisodeResult(
            ret=self.ret, loaded=W, phi_final=s.phi_shovel, reached_end_zone=outcome == "success",
            failed=outcome == "failure", truncated=truncated, steps=self.steps,
            elapsed_s=self.steps * self.p.control_dt, front_drift_pct=drift_pct(self._front),
            rear_drift_pct=drift_pct(self._rear),
            success_level=success_level(W, s.phi_shovel, self.p.phi_thresh_pitch),
            alpha_deg=math.degrees(self.sim.pile.alpha), material=self.sim.material,
            max_tilt_deg=math.degrees(self._max_tilt),
        )

    def refused_result(self) -> EpisodeResult:
        """The result of this episode not run because the controller refuses its told slope
        (slope_refusal): nothing loaded, no time, as on the machine where the policy node commands
        zero and the supervisor does not arm. Call right after reset."""
        if not self.slope_refusal:
            raise RuntimeError("refused_result() for an episode whose told slope is inside the trained range")
        s = self._state
        return EpisodeResult(
            ret=0.0, loaded=0.0, phi_final=s.phi_shovel, reached_end_zone=False, failed=False, truncated=False,
            steps=0, elapsed_s=0.0, front_drift_pct=0.0, rear_drift_pct=0.0, success_level=0,
            alpha_deg=math.degrees(self.sim.pile.alpha), material=self.sim.material,
            max_tilt_deg=math.degrees(self._max_tilt), refused=True)

    @property
    def state(self):
        """The machine's true state (the simulator's)."""
        return self._state

    @property
    def measured_state(self):
        """The state as the machine's sensors give it (the arm's angle-sensor offsets of the episode's
        conditions applied: _measured, once a step); what a controller on the machine computes from the topics."""
        return self._m



def warm_up(env, seed: int = 0, steps: int = 3) -> float:
    """One reset (the attack drive into a pile) and `steps` control steps pushing into it with the arm
    moving, so that the compiled physics (numba kernels, kept on disk after their first compilation and
    compiled again after an install or a change of their sources) is compiled now. A node calls it before
    its first status: on a fresh install the first step of an attempt otherwise took 3-17 s on a loaded
    2-core host, during which a realtime sim node published nothing and the policy node ended the
    attempt (status_timeout 1.5 s; `make demo`'s first attempt timed out, a review of 2026-12-01). The
    environment is left mid-episode: the caller resets it. Best effort: a pile whose attack stalls is
    left as it is (the caller's own reset says why). Returns the seconds it took."""
    t0 = time.perf_counter()
    try:
        reset_or_redraw(env, seed, {}, log=lambda *_: None)
        for _ in range(steps):
            _, _, term, trunc, _ = env.step(np.ones(3))
            if term or trunc:
                break
    except (AttackError, SimulationError):
        pass
    return time.perf_counter() - t0


def reset_or_redraw(env, seed_k: int, options: dict, log=print):
    """env.reset on the episode's seed; where the attack drive cannot bury the bucket (AttackError:
    under randomised conditions a slow attack on the steepest piles, about 1 reset in 60 on 35 deg
    ones, stalls a few mm short of d_init) the episode's pile and conditions are drawn again from
    the seeds (seed_k, r), r = 1..ATTACK_REDRAWS, deterministically (a resume replays them), at the
    same slope. A stalled attack is not a transition the learner can use; it must not end the run.
    MuJoCo finding the attack drive unstable (SimulationError) is redrawn in the same way.
    Returns the first observation."""
    own, env.attack_redraws = env.attack_redraws, 0        # the redraws here, seeded, as every run before
    try:
        try:
            return env.reset(seed=seed_k, options=options)[0]
        except (AttackError, SimulationError) as e:
            first = e
        for r in range(1, ATTACK_REDRAWS + 1):
            try:
                obs = env.reset(seed=int(np.random.default_rng([seed_k, r]).integers(2**31 - 1)), options=options)[0]
            except (AttackError, SimulationError):
                continue
            log(f"episode seed {seed_k}: {first}; its pile drawn again ({r} redraw{'s' if r > 1 else ''})")
            return obs
        raise first
    finally:
        env.attack_redraws = own
