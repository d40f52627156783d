"""Domain randomisation (issue 14): what differs between the simulator and the machine (ROS-free).

Two kinds, applied where they act on the machine:

* **Episode conditions** (:class:`Conditions`), drawn once per episode by :func:`draw`:
  the error of the LiDAR's slope estimate, the camera speed's delay, the actuators' dead time
  (drive and hydraulics separately), the material (density, friction, cohesion, rocks), the tyre
  friction, the start distance, attack speed, heading and lateral offset of a machine placed by
  hand. The simulator applies the physical ones (``LhdSimulator.reset(conditions=...)``), the
  environment the observation ones.
* **Sensor noise** (:class:`ObservationCorruptor`), every control step: noise on the observed
  slope and v_x, camera dropouts (v_x keeps its last value, as the policy node keeps the newest
  odometry until input_timeout) and the camera delay.

Ranges come from the config's ``randomization`` section (each with its reason there and in
docs/training.md). :data:`NOMINAL` is the paper's protocol: nothing changes.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import asdict, dataclass, replace

import numpy as np

from lhd_loading_ros.task.pile import SoilRanges


@dataclass(frozen=True)
class Conditions:
    """One episode's departures from the nominal simulator. Angles in degrees, lengths in m."""
    slope_error_deg: float = 0.0        # observed alpha - true alpha (before the per-step noise)
    slope_noise_deg: float = 0.0        # sd of the per-step noise on the observed alpha
    vx_noise: float = 0.0               # m/s, sd of the per-step noise on the observed v_x
    vx_dropout_probability: float = 0.0
    vx_dropout_max_steps: int = 0
    vx_delay_steps: int = 0             # the observed v_x is this many control steps old
    drive_delay_s: float = 0.0          # a wheel command takes effect this late
    hydraulic_delay_s: float = 0.0      # a boom / bucket command takes effect this late
    soil: SoilRanges | None = None      # None: the config's pile ranges
    tyre_friction: float | None = None  # None: machine.wheel_friction
    d_attack: float | None = None       # None: the paper's U(d_attack_min, d_attack_max)
    attack_speed_fraction: float | None = None   # of wheels_max; None: U(sim.attack_speed_min_fraction, 1)
    heading_deg: float = 0.0            # start yaw of the machine (positive: nose to +y)
    lateral_offset: float = 0.0         # m, the lip's centre off the pile's axis at the start
    surface_sd: float = 0.0             # m, sd of the pile surface's relief about its plane (0: a plane)
    surface_corr: float = 0.15          # m, the relief's correlation length (VoxelPile.roughen)
    drive_gain: float = 1.0             # the wheels turn at this times the commanded speed (battery, speed loop)
    hydraulic_gain: float = 1.0         # the boom and bucket move at this times the commanded rate (pump flow)
    rest_start: bool = False            # after the drive in, the machine stops: the episode starts from rest with
                                        # the tip in the pile, as an attempt on the machine does (LhdSimulator.come_to_rest)
    boom_offset_deg: float = 0.0        # the measured boom angle minus the true one: the sensor's zero taken off the
    bucket_offset_deg: float = 0.0      # attack pose (likewise the bucket's); the tip and its pitch are computed from
                                        # the measured angles, for the policy and for the zones that end the attempt
    arm_angle_noise_deg: float = 0.0    # sd of the noise on each sample of the boom and bucket angles (a potentiometer's
    arm_encoder_counts: int = 0         # ADC), and the counts per turn they are read in (an encoder's; 0: exact). Either
                                        # set: the rates are the Due's, differences of the samples over its rate window
                                        # (task/arm_sensors.py), not the joints' velocities
    drift_flag_lag_max_s: float = 0.0   # the observed drift flag is over a control period that ends 0..this (U on the
                                        # FEE chunk grain, each step) before the observation: the bridge's window ends at
                                        # its newest camera image (LhdSimulator.drift_flag); 0: the period since the last
                                        # command, the simulator's own (wheel_drift)

    def summary(self) -> dict:
        """A flat dict of the drawn values (for info and CSVs)."""
        d = asdict(self)
        soil = d.pop("soil")
        d["density_range"] = None if soil is None else list(soil["density"])
        return d


NOMINAL = Conditions()


@dataclass(frozen=True)
class RandomizationRanges:
    enabled: bool
    slope_error_max_deg: float
    slope_noise_deg: float
    vx_noise: float
    vx_dropout_probability: float
    vx_dropout_max_steps: int
    vx_delay_steps_max: int
    actuator_delay_max_s: float
    soil: SoilRanges                    # the pile's ranges widened by the section's
    tyre_friction: tuple[float, float]
    d_attack: tuple[float, float]
    attack_speed_min_fraction: float
    heading_max_deg: float
    lateral_offset_max: float
    chunk_s: float                      # the grain of the actuator delay (one FEE chunk)
    drive_gain: tuple[float, float] = (1.0, 1.0)
    hydraulic_gain: tuple[float, float] = (1.0, 1.0)
    zones_from_slope_estimate: bool = False   # a slope-estimate error also moves the zones (task/zones.py)
    rest_start_share: float = 0.0       # this share of the episodes starts from rest (Conditions.rest_start)
    surface_sd_max: float = 0.0         # m, each pile's relief sd U(0, this) about its plane (Conditions.surface_sd)
    zones_at_nominal_density: bool = False   # the zones built as the end-zone node does (task/end_zone.py)
    arm_offset_max_deg: float = 0.0     # each episode's boom and bucket angle-sensor offsets, each U(-this, this)
    slope_error_high_share: float = 0.0  # this share of the episodes told too steep: error U(max / 2, max)
    drift_flag_lag_max_s: float = 0.0   # s: the observed drift window's lag, up to this (Conditions.drift_flag_lag_max_s)
    slope_error_small_share: float = 0.0   # this share of the episodes: error U(-small_max, small_max), the LiDAR right
    slope_error_small_max_deg: float = 0.0

    @classmethod
    def from_config(cls, cfg: dict) -> "RandomizationRanges":
        r = cfg["randomization"]
        base = SoilRanges.from_config(cfg)
        soil = replace(base, density=(r["density_min"], r["density_max"]),
                       phi=(math.radians(r["phi_min_deg"]), math.radians(r["phi_max_deg"])),
                       cohesion=(base.cohesion[0], max(base.cohesion[1], r["cohesion_max"])),
                       rocks=(base.rocks[0], r["rocks_max"]))
        return cls(
            enabled=bool(r["enabled"]), slope_error_max_deg=r["slope_error_max_deg"],
            slope_noise_deg=r["slope_noise_deg"], vx_noise=r["vx_noise"],
            vx_dropout_probability=r["vx_dropout_probability"], vx_dropout_max_steps=int(r["vx_dropout_max_steps"]),
            vx_delay_steps_max=int(r["vx_delay_steps_max"]), actuator_delay_max_s=r["actuator_delay_max_s"],
            soil=soil, tyre_friction=(r["tyre_friction_min"], r["tyre_friction_max"]),
            d_attack=(cfg["paper"]["episode"]["d_attack_min"], r["d_attack_max"]),
            attack_speed_min_fraction=r["attack_speed_min_fraction"], heading_max_deg=r["heading_max_deg"],
            lateral_offset_max=r["lateral_offset_max"],
            chunk_s=cfg["sim"]["timestep"] * cfg["sim"]["fee_every"],
            drive_gain=(r.get("drive_gain_min", 1.0), r.get("drive_gain_max", 1.0)),
            hydraulic_gain=(r.get("hydraulic_gain_min", 1.0), r.get("hydraulic_gain_max", 1.0)),
            zones_from_slope_estimate=bool(r.get("zones_from_slope_estimate", 0)),
            rest_start_share=float(r.get("rest_start_share", 0.0)),
            surface_sd_max=float(r.get("surface_sd_max", 0.0)),
            zones_at_nominal_density=bool(r.get("zones_at_nominal_density", 0)),
            arm_offset_max_deg=float(r.get("arm_offset_max_deg", 0.0)),
            slope_error_high_share=float(r.get("slope_error_high_share", 0.0)),
            drift_flag_lag_max_s=float(r.get("drift_flag_lag_max_s", 0.0)),
            slope_error_small_share=float(r.get("slope_error_small_share", 0.0)),
            slope_error_small_max_deg=float(r.get("slope_error_small_max_deg", 0.0)),
        )


def draw(rng: np.random.Generator, rr: RandomizationRanges) -> Conditions:
    """One episode's conditions, uniform within the ranges (delays on the chunk grain)."""
    n_delay = int(math.floor(rr.actuator_delay_max_s / rr.chunk_s + 1e-9))
    u = rng.uniform
    c = Conditions(
        slope_error_deg=float(u(-rr.slope_error_max_deg, rr.slope_error_max_deg)),
        slope_noise_deg=rr.slope_noise_deg, vx_noise=rr.vx_noise,
        vx_dropout_probability=rr.vx_dropout_probability, vx_dropout_max_steps=rr.vx_dropout_max_steps,
        vx_delay_steps=int(rng.integers(0, rr.vx_delay_steps_max + 1)),
        drive_delay_s=rr.chunk_s * int(rng.integers(0, n_delay + 1)),
        hydraulic_delay_s=rr.chunk_s * int(rng.integers(0, n_delay + 1)),
        soil=rr.soil, tyre_friction=float(u(*rr.tyre_friction)),
        d_attack=float(u(*rr.d_attack)), attack_speed_fraction=float(u(rr.attack_speed_min_fraction, 1.0)),
        heading_deg=float(u(-rr.heading_max_deg, rr.heading_max_deg)),
        lateral_offset=float(u(-rr.lateral_offset_max, rr.lateral_offset_max)),
    )
    # drawn last, and only where a range is set: with the gains off (1, 1) every other draw is what
    # it was before they existed, so earlier randomised evaluations replay exactly
    gains = {}
    if rr.drive_gain != (1.0, 1.0):
        gains["drive_gain"] = float(u(*rr.drive_gain))
    if rr.hydraulic_gain != (1.0, 1.0):
        gains["hydraulic_gain"] = float(u(*rr.hydraulic_gain))
    if rr.rest_start_share > 0.0:       # likewise drawn last, only where set
        gains["rest_start"] = bool(rng.random() < rr.rest_start_share)
    if rr.surface_sd_max > 0.0:         # likewise; the correlation length the stress case's (the largest rock)
        gains["surface_sd"] = float(u(0.0, rr.surface_sd_max))
        gains["surface_corr"] = ROUGH_CORR
    if rr.arm_offset_max_deg > 0.0:     # likewise: the arm's angle sensors zeroed off the attack pose
        gains["boom_offset_deg"] = float(u(-rr.arm_offset_max_deg, rr.arm_offset_max_deg))
        gains["bucket_offset_deg"] = float(u(-rr.arm_offset_max_deg, rr.arm_offset_max_deg))
    if rr.slope_error_high_share > 0.0 and rng.random() < rr.slope_error_high_share:
        # likewise: a LiDAR slope told too steep by half the range or more, where the uniform draw gives one
        # episode in four; the case the actors fail most (a shallow pile's end zone told short: docs/training.md
        # "How much a slope told too high can give")
        gains["slope_error_deg"] = float(u(0.5 * rr.slope_error_max_deg, rr.slope_error_max_deg))
    if rr.slope_error_small_share > 0.0 and rng.random() < rr.slope_error_small_share:
        # likewise: the slope estimate as the LiDAR node gives it on a plane pile (within 0.28 deg in the twin, docs/twin.md;
        # a rough face errs more, docs/perception.md),
        # in this share of the episodes, the whole range's error in the others. It decides over the told-too-steep
        # share above (a small error replaces a drawn large one), so the two shares multiply as documented in config/
        gains["slope_error_deg"] = float(u(-rr.slope_error_small_max_deg, rr.slope_error_small_max_deg))
    if rr.drift_flag_lag_max_s > 0.0:   # no draw here: the lag is drawn each step (the environment's _obs)
        gains["drift_flag_lag_max_s"] = rr.drift_flag_lag_max_s
    return replace(c, **gains) if gains else c


def delay_chunks(delay_s: float, chunk_s: float, chunks_per_step: int) -> int:
    """Chunks of a control period that still run the previous command. A delay longer than a
    control period is refused (the simulator keeps only the previous command)."""
    n = int(round(delay_s / chunk_s))
    if not (0 <= n <= chunks_per_step) or abs(n * chunk_s - delay_s) > 1e-9:
        raise ValueError(f"actuator delay {delay_s!r} s must be a multiple of the {chunk_s:g} s chunk "
                         f"within one control period (0..{chunks_per_step * chunk_s:g} s)")
    return n


class ObservationCorruptor:
    """Per-step sensor errors on the observed v_x and slope of one episode.

    ``observe(v_x_true, alpha_true)`` returns what the policy sees this step: v_x from
    ``vx_delay_steps`` steps ago plus Gaussian noise, or, in a dropout, the value it saw last
    step (a run of at most ``vx_dropout_max_steps``); alpha plus the episode's error plus
    Gaussian noise (radians in, radians out). With NOMINAL it returns its inputs unchanged and
    draws nothing from the generator."""

    def __init__(self, c: Conditions, rng: np.random.Generator):
        self.c, self.rng = c, rng
        self._vx = deque(maxlen=c.vx_delay_steps + 1)
        self._last_vx: float | None = None
        self._held = 0

    def observe(self, v_x: float, alpha: float) -> tuple[float, float]:
        c, rng = self.c, self.rng
        self._vx.append(float(v_x))
        vx = self._vx[0]                                   # the oldest kept: delay steps ago (fewer at the start)
        if c.vx_noise > 0.0:
            vx += float(rng.normal(0.0, c.vx_noise))
        if (self._last_vx is not None and c.vx_dropout_probability > 0.0 and self._held < c.vx_dropout_max_steps
                and rng.random() < c.vx_dropout_probability):
            vx = self._last_vx                             # no new frame: the last speed stands
            self._held += 1
        else:
            self._held = 0
        self._last_vx = vx
        a = float(alpha) + math.radians(c.slope_error_deg)
        if c.slope_noise_deg > 0.0:
            a += math.radians(float(rng.normal(0.0, c.slope_noise_deg)))
        return vx, a


def stress_conditions(name: str, i: int, cfg: dict) -> Conditions:
    """The conditions of evaluation episode i under a named stress case (`lhd eval --stress`):
    fixed departures at the corners of what issue 14 asks an actor to survive, not draws.

    placement  the machine placed by hand, heading +-3 deg and lip +-5 cm off the pile's axis
               (signs alternate over the episodes: (i // 8) % 2 and (i // 16) % 2, so each sign pair
               meets every slope and material), with the camera's speed noise, dropouts and a
               one-step delay (the section's values) and 100 ms actuator dead time on both channels
    sensors    only the camera's noise, dropouts and delay
    delay      only 100 ms actuator dead time on both channels
    light      gravel at the light end of the section's density range (its lowest 100 kg/m^3:
               loose, dry), the pile's other ranges as configured
    dense      gravel at the dense end (its highest 100 kg/m^3: dense, moist)
    rocky      every pile nonhomogeneous (STRESS_MATERIAL) with the section's rocks_max rocks of
               8-15 cm (12, against the paper's piles' 3-8; a rock that finds no room in a shallow
               wedge is left out, as in every pile): the nominal evaluation puts rocks in half its
               piles, this case in all of them, as many as training ever drew
    slow_drive  every wheel at SLOW_DRIVE_GAIN (0.8) of its commanded speed
    slow_hydraulics  boom and bucket at SLOW_HYDRAULIC_GAIN (0.75) of their commanded rates
    cohesive   moist gravel with fines: every pile's apparent cohesion at COHESIVE_PA (1,500 Pa; the
               pile's gravel is cohesionless, the randomisation section draws up to its cohesion_max),
               its other ranges as configured. A fixed figure, not the section's end, so that actors
               trained on different files meet the same material
    dense_placement  placement and dense together: the machine placed by hand (as `placement`, with the
               camera's errors and the 100 ms dead time) in front of the dense gravel of `dense`. Each
               passes alone; together they cost rld_twin 12 % of its attempts (a review, 2026-11-28:
               dense shallow piles leave loads 1-4 kg above the 20 kg, and an attempt off the
               pile's axis loses those kg; docs/training.md "Combined departures"), so the pair is named
    rest       every attempt starts from rest with the tip d_init in the pile (LhdSimulator.come_to_rest; where a
               stalled drive left it with sim.attack_min_depth), as
               an attempt on the machine and in the digital twin does (the supervisor arms a machine that
               stands in the attack pose), not at the attack speed of the paper's episodes; nothing else
               changes. The tyres may slip while the machine accelerates with its bucket in the pile, and
               the drift flags say so (docs/modeling.md "A start from rest")
    machine    every attempt as one on the machine goes: placed by hand (as `placement`, with the camera's
               errors and the 100 ms dead time), from rest with the tip in the pile (as `rest`), on a pile
               whose surface is no plane (as `rough`, the observed slope the scanned slice's). Each passes
               alone; an attempt on the machine has them all at once (2026-11-29)
    calibration  the arm's angle sensors zeroed off the attack pose: the boom's reads CALIBRATION_OFFSET_DEG (2 deg)
               more or less than the true angle, and the bucket's likewise (signs alternate over the episodes:
               (i // 8) % 2 for the boom, (i // 16) % 2 for the bucket, so each sign pair meets every slope and
               material). On the machine the Due reports the angles as 0 in the attack pose (docs/serial_protocol.md)
               and the tip, its pitch, the policy's observation and the end test of the supervisor all follow
               from them through the arm's kinematics; the machine itself, its load and its true final pitch
               (the success test) do not change
    arm_noise  the arm's angle sensors as the Due reads them: each sample of the boom and bucket angles with
               ARM_NOISE_DEG (0.1 deg) of noise, in ARM_ENCODER_COUNTS (4,096) counts per turn, and the rates the
               firmware's differences of those samples over its rate window (task/arm_sensors.py, 0.1 s), not the
               joints' velocities. The tip and its pitch follow the measured angles, as in `calibration`
    rest_bridge  every attempt from rest (as `rest`) with the drift flags the machine's bridge gives: over a control
               period ending 0..DRIFT_FLAG_LAG_S before each observation (Conditions.drift_flag_lag_max_s), as its window
               ends at the newest camera image, so that a window straddles the start where the simulator's own
               (the period since the last command) never does (docs/modeling.md "A start from rest")
    machine_bridge  `machine` with the bridge's drift flags of `rest_bridge`
    rough      the pile's surface not a plane: a random relief of sd ROUGH_SD (3 cm) and correlation
               length ROUGH_CORR (15 cm) about it (VoxelPile.roughen). A pile dumped by a feeder or by
               hand has bumps of about the size of its largest pieces (the paper's 8-15 cm rocks in 2-5
               cm gravel); the simulator's piles, in training too, are planes. The observed slope is
               the centre slice's own (VoxelPile.slice_slope; the environment adds its difference
               from the plane to the slope error): what the machine's LiDAR, scanning that slice,
               measures at best
    """
    r = cfg["randomization"]
    sensors = dict(vx_noise=r["vx_noise"], vx_dropout_probability=r["vx_dropout_probability"],
                   vx_dropout_max_steps=int(r["vx_dropout_max_steps"]), vx_delay_steps=int(r["vx_delay_steps_max"]),
                   slope_noise_deg=r["slope_noise_deg"])
    delay = dict(drive_delay_s=0.1, hydraulic_delay_s=0.1)
    if name == "placement":
        return Conditions(heading_deg=3.0 if (i // 8) % 2 == 0 else -3.0,
                          lateral_offset=0.05 if (i // 16) % 2 == 0 else -0.05, **sensors, **delay)
    if name == "sensors":
        return Conditions(**sensors)
    if name == "delay":
        return Conditions(**delay)
    if name in ("light", "dense"):
        lo, hi = r["density_min"], r["density_max"]
        band = (lo, min(hi, lo + 100.0)) if name == "light" else (max(lo, hi - 100.0), hi)
        return Conditions(soil=replace(SoilRanges.from_config(cfg), density=band))
    if name == "dense_placement":
        return replace(stress_conditions("placement", i, cfg), soil=stress_conditions("dense", i, cfg).soil)
    if name == "machine":
        return replace(stress_conditions("placement", i, cfg), rest_start=True, surface_sd=ROUGH_SD,
                       surface_corr=ROUGH_CORR)
    if name == "machine_bridge":
        return replace(stress_conditions("machine", i, cfg), drift_flag_lag_max_s=DRIFT_FLAG_LAG_S)
    if name == "rest_bridge":
        return Conditions(rest_start=True, drift_flag_lag_max_s=DRIFT_FLAG_LAG_S)
    if name == "rocky":
        n = int(r["rocks_max"])
        return Conditions(soil=replace(SoilRanges.from_config(cfg), rocks=(n, n)))
    if name == "rough":
        return Conditions(surface_sd=ROUGH_SD, surface_corr=ROUGH_CORR)
    if name == "calibration":
        return Conditions(boom_offset_deg=CALIBRATION_OFFSET_DEG * (1.0 if (i // 8) % 2 == 0 else -1.0),
                          bucket_offset_deg=CALIBRATION_OFFSET_DEG * (1.0 if (i // 16) % 2 == 0 else -1.0))
    if name == "arm_noise":
        return Conditions(arm_angle_noise_deg=ARM_NOISE_DEG, arm_encoder_counts=ARM_ENCODER_COUNTS)
    if name == "rest":
        return Conditions(rest_start=True)
    if name == "slow_drive":
        return Conditions(drive_gain=SLOW_DRIVE_GAIN)
    if name == "slow_hydraulics":
        return Conditions(hydraulic_gain=SLOW_HYDRAULIC_GAIN)
    if name == "cohesive":
        return Conditions(soil=replace(SoilRanges.from_config(cfg), cohesion=(COHESIVE_PA, COHESIVE_PA)))
    raise ValueError(f"unknown stress case {name!r}; expected one of {', '.join(STRESS_CASES)}")


STRESS_CASES = ("placement", "sensors", "delay", "light", "dense", "rocky", "rough", "slow_drive", "slow_hydraulics",
                "cohesive", "dense_placement", "rest", "machine", "calibration", "arm_noise", "rest_bridge", "machine_bridge")
DRIFT_FLAG_LAG_S = 0.14     # s: the bridge's drift window ends at its newest camera image, which the ArUco node's
                            # odometry delivers 20-110 ms after the exposure (measured in the twin; the comment on
                            # bridge_core.DRIFT_ODOM_MAX_AGE), read by the policy up to a 20 ms sensor frame later:
                            # 0.02-0.13 s, and 0 included. Not modelled: a window older still while the camera drops
                            # images (the bridge takes one up to DRIFT_ODOM_MAX_AGE, 0.3 s, old). Drawn each step,
                            # capped so that the window's end never goes back, as on the machine (env.drift_lag_chunks)
SLOW_DRIVE_GAIN = 0.8       # the wheels at 80 % of the commanded speed: a battery near its cut-off (a DC motor's
                            # speed follows its voltage; about -20 % from full charge) or a speed loop 20 % off
SLOW_HYDRAULIC_GAIN = 0.75  # boom and bucket at 75 % of the commanded rate: less pump flow (a sagging battery
                            # under the pump motor, cold oil) or valves opening less than calibrated
COHESIVE_PA = 1500.0        # Pa: apparent (capillary) cohesion of moist gravel with fines, the upper end of what a
                            # draw point's wet muck shows (Tampier et al. 2021 name humidity raising cohesion among
                            # what makes loading hard); clean dry gravel 0 (pile.cohesion_*)
CALIBRATION_OFFSET_DEG = 2.0   # deg: an angle sensor zeroed by eye on a pose ("bucket plate flat on the floor, boom
                               # down"); a digital inclinometer on the plate gets within about 0.1-0.5 deg
ROUGH_SD = 0.03        # m: half the largest rock (8-15 cm) of the paper's pile, three 2-5 cm grains
ROUGH_CORR = 0.15      # m: the largest rock's size
# the material a stress case puts every episode on (the others keep the evaluation's alternation)
STRESS_MATERIAL = {"rocky": "nonhomogeneous"}
ARM_NOISE_DEG = 0.1         # deg, sd per sample: a potentiometer on the Due's 12-bit ADC over about 300 deg reads
                            # 0.073 deg a count; 0.1 deg is 1.4 counts of supply and motor noise
ARM_ENCODER_COUNTS = 4096   # counts per turn: a 12-bit absolute encoder (0.088 deg a count)
