"""Domain randomisation in the simulator and the environment: actuator dead time, the machine
placed by hand, tyre friction, the material, and the sensor errors reaching the observation only."""
import math

import numpy as np
import pytest

from lhd_loading_ros.task.randomization import NOMINAL, Conditions
from lhd_sim_node.env import LhdLoadingEnv
from lhd_sim_node.simulator import LhdSimulator


@pytest.fixture(scope="module")
def cfg():
    from lhd_loading_ros.task.config import load_config
    return load_config()


def _sim_state(sim):
    return np.concatenate([sim.data.qpos, sim.data.qvel, sim.data.act])


def _pair(cfg, cond):
    """Two simulators on the same pile: one nominal, one under `cond`'s delays."""
    a, b = LhdSimulator(cfg), LhdSimulator(cfg)
    fixed = dict(alpha=math.radians(20.0), material="homogeneous", d_attack=0.15, attack_speed=2.7)
    a.reset(np.random.default_rng(4), **fixed)
    b.reset(np.random.default_rng(4), conditions=cond, **fixed)
    np.testing.assert_array_equal(_sim_state(a), _sim_state(b))     # delays change nothing before the first command
    return a, b


def test_a_delay_of_one_period_runs_the_previous_command_for_that_period(cfg):
    """Hydraulic dead time of 100 ms = one control period: the first period after the attack
    still runs the attack's arm command (arm still), the wheels take the new one; from the second
    period on, both run what was commanded one period earlier. Bit-identical to a nominal
    simulator fed those commands (MuJoCo is deterministic)."""
    a, b = _pair(cfg, Conditions(hydraulic_delay_s=0.1))
    u1 = np.array([2.0, -0.191, 0.2])          # drive, lift, curl
    u2 = np.array([1.0, 0.0, 0.2])             # stop lifting, keep curling
    b.step(u1)
    a.step(np.array([u1[0], 0.0, 0.0]))        # the attack left the arm still
    np.testing.assert_array_equal(_sim_state(a), _sim_state(b))
    b.step(u2)
    a.step(np.array([u2[0], u1[1], u1[2]]))    # the arm one period late
    np.testing.assert_array_equal(_sim_state(a), _sim_state(b))
    # the same for the drive channel
    a, b = _pair(cfg, Conditions(drive_delay_s=0.1))
    b.step(np.array([0.0, -0.191, 0.0]))
    a.step(np.array([2.7, -0.191, 0.0]))       # the wheels keep the attack's speed for a period
    np.testing.assert_array_equal(_sim_state(a), _sim_state(b))


def test_a_partial_delay_starts_the_boom_later(cfg):
    """A 40 ms hydraulic dead time inside a 100 ms period: the boom lifts for the last 60 ms of
    the first period instead of 100 ms. The joint's travel over the period: the valve-limited
    speed 0.191 rad/s times the time it was open, less the servo's start-up transient in both;
    the ratio is about 0.06 / 0.1 = 0.6 (between 0.45 and 0.75 with the transient)."""
    a, b = _pair(cfg, Conditions(hydraulic_delay_s=0.04))
    q0 = float(a.data.qpos[a.boom_q])
    u = np.array([0.0, -0.191, 0.0])
    a.step(u)
    b.step(u)
    da, db = q0 - float(a.data.qpos[a.boom_q]), q0 - float(b.data.qpos[b.boom_q])
    assert da > 0.01                                     # the undelayed boom lifted (negative angle is up)
    assert 0.45 < db / da < 0.75, (da, db)


def test_a_machine_placed_by_hand(cfg):
    sim = LhdSimulator(cfg)
    sim.new_pile(np.random.default_rng(0), math.radians(20.0), "homogeneous")
    heading, lateral = math.radians(3.0), 0.05
    sim.place_machine(0.15, heading, lateral)
    tip = sim.data.site_xpos[sim.sid_tip]
    assert tip[1] == pytest.approx(lateral, abs=1e-5)                 # the lip's centre is where it was put
    assert tip[0] == pytest.approx(-0.15, abs=1e-3)                   # d_attack before the toe (x of a 0.4 m lip)
    w, x, y, z = sim.data.qpos[3:7]
    assert math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)) == pytest.approx(heading, abs=1e-9)
    # the bucket's slices: the pile's slice centres within the lip's width around y = 0.05 (computed here)
    yc = sim.pile.y_centers
    expect = [j for j in range(len(yc)) if lateral - 0.2 <= yc[j] <= lateral + 0.2]
    assert list(sim._slices) == expect and len(expect) < len(yc)
    # and a full reset with the same conditions: the attack drive keeps the heading (no steering)
    sim.reset(np.random.default_rng(0), alpha=math.radians(20.0), material="homogeneous",
              conditions=Conditions(heading_deg=3.0, lateral_offset=0.05, d_attack=0.15, attack_speed_fraction=1.0))
    w, x, y, z = sim.data.qpos[3:7]
    assert math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))) == pytest.approx(3.0, abs=0.3)
    # it drove about 0.25 m along its heading: the lip moved sideways by about 0.25 sin 3 deg = 1.3 cm
    assert sim.data.site_xpos[sim.sid_tip][1] == pytest.approx(0.05 + 0.25 * math.sin(heading), abs=0.006)


def test_tyre_friction_and_soil_are_per_episode(cfg):
    sim = LhdSimulator(cfg)
    wheels = sim._wheel_geoms
    sim.reset(np.random.default_rng(1), conditions=Conditions(tyre_friction=0.6))
    assert all(sim.model.geom_friction[g, 0] == 0.6 for g in wheels)
    sim.reset(np.random.default_rng(1))
    assert all(sim.model.geom_friction[g, 0] == cfg["machine"]["wheel_friction"] for g in wheels)
    # the randomised soil ranges reach the pile: over 40 homogeneous piles the densities span more than
    # the paper's gravel range (1,760-2,000) and stay inside the section's (1,500-2,200)
    from lhd_loading_ros.task.randomization import RandomizationRanges
    soil = RandomizationRanges.from_config(cfg).soil
    rng = np.random.default_rng(2)
    rho = []
    for _ in range(40):
        sim.new_pile(rng, math.radians(20.0), "homogeneous", soil=soil)
        rho.append(float(np.median(sim.pile.density)))
    assert min(rho) >= 1500 * 0.9 and max(rho) <= 2200 * 1.1            # voxels jitter around the pile's draw
    assert min(rho) < 1700 and max(rho) > 2050


def test_the_environment_draws_conditions_and_only_the_observation_sees_sensor_errors(cfg):
    a = LhdLoadingEnv("rld", cfg, randomize=True)
    b = LhdLoadingEnv("rld", cfg, randomize=True)
    oa, ia = a.reset(seed=11)
    ob, ib = b.reset(seed=11)
    np.testing.assert_array_equal(oa, ob)                      # reproducible from the seed
    assert ia["conditions"] == ib["conditions"] != NOMINAL
    c = ia["conditions"]
    p = a.p
    told = math.radians(ia["alpha_deg"] + c.slope_error_deg)
    expect = min(1.0, max(0.0, (told - p.alpha_min) / (p.alpha_max - p.alpha_min)))
    # the observed slope: the true one plus the episode's error, within the per-step noise (4 sd)
    sd = math.radians(c.slope_noise_deg) / (p.alpha_max - p.alpha_min)
    assert oa[11] == pytest.approx(expect, abs=4 * sd + 1e-6)
    # the reward and the outcome come from the true state: the same episode with the sensor errors switched
    # off after the reset (same pile, same physical conditions) gives the same rewards and outcomes
    n = b
    n._sensors = None
    rng = np.random.default_rng(0)
    for _ in range(15):
        act = rng.uniform(-1, 1, 3)
        ra, rn = a.step(act), n.step(act)
        assert ra[1] == rn[1] and ra[2] == rn[2]
        assert ra[4]["loaded_mass"] == rn[4]["loaded_mass"]
        if ra[2] or ra[3]:
            break
    # the observed v_x differs from the true one (noise), every other entry is the same
    diff = np.nonzero(ra[0] != rn[0])[0].tolist()
    assert set(diff) <= {4, 11} and 4 in diff


def test_bad_conditions_are_refused(cfg):
    env = LhdLoadingEnv("rld", cfg)
    with pytest.raises(ValueError, match="options\\['conditions'\\] must be"):
        env.reset(seed=0, options={"conditions": {"heading_deg": 3}})
    with pytest.raises(ValueError, match="multiple of the 0.02 s chunk"):
        env.reset(seed=0, options={"conditions": Conditions(drive_delay_s=0.03)})


def test_stress_cases_in_the_evaluation(cfg):
    """`lhd eval --stress placement`: every episode at a corner of heading +-3 deg and lip +-5 cm,
    all four corners used, with the sensors' errors and 100 ms dead time on both channels."""
    from lhd_loading_ros.learning.evaluate import evaluate
    from lhd_loading_ros.task.randomization import stress_conditions

    env = LhdLoadingEnv("rld", cfg)
    seen = []

    def policy(obs):
        if env.steps == 0:
            seen.append(env.conditions)
        return np.array([1.0, 1.0, 1.0])       # drive, lift and curl at full speed

    res = evaluate(env, policy, 32, 5, cfg["task"]["bucket_capacity"], breakdown=False, stress="placement")
    assert res["episodes"] == 32 and len(seen) == 32
    assert {(c.heading_deg, c.lateral_offset) for c in seen} == {(3.0, 0.05), (-3.0, 0.05), (3.0, -0.05), (-3.0, -0.05)}
    assert all(c.drive_delay_s == c.hydraulic_delay_s == 0.1 for c in seen)
    assert all(c.vx_noise == cfg["randomization"]["vx_noise"] and c.slope_error_deg == 0.0 for c in seen)
    assert stress_conditions("sensors", 0, cfg).drive_delay_s == 0.0
    assert stress_conditions("delay", 0, cfg).vx_noise == 0.0
    assert stress_conditions("light", 0, cfg).soil.density == (1500.0, 1600.0)
    assert stress_conditions("dense", 0, cfg).soil.density == (2100.0, 2200.0)
    for i in (0, 8, 16, 24):    # the pair: placement's corner of episode i on the dense gravel, nothing else
        pair, place = stress_conditions("dense_placement", i, cfg), stress_conditions("placement", i, cfg)
        assert pair.soil.density == (2100.0, 2200.0) and place.soil is None
        assert {k: v for k, v in pair.summary().items() if k != "density_range"} == \
            {k: v for k, v in place.summary().items() if k != "density_range"}
    with pytest.raises(ValueError, match="unknown stress case 'wind'; expected one of placement, sensors, delay, light"):
        stress_conditions("wind", 0, cfg)


def test_rocky_stress_case_puts_the_most_rocks_in_every_pile(cfg):
    """`--stress rocky`: every evaluation pile nonhomogeneous, holding randomization.rocks_max
    rocks (as many as fit: counted here from the voxels that took the rock density), where the
    nominal evaluation alternates gravel-only and 3-8-rock piles."""
    from lhd_loading_ros.learning.evaluate import evaluate

    env = LhdLoadingEnv("rld", cfg)
    piles = []

    def policy(obs):
        if env.steps == 0:
            p = env.sim.pile
            piles.append((env.sim.material, p.rocks, int((p.density == cfg["pile"]["rock_density"]).sum())))
        return np.array([1.0, 1.0, 1.0])

    evaluate(env, policy, 8, 11, cfg["task"]["bucket_capacity"], breakdown=False, stress="rocky")
    n_max = cfg["randomization"]["rocks_max"]
    assert len(piles) == 8 and all(m == "nonhomogeneous" for m, _, _ in piles)
    assert all(8 < n <= n_max for _, n, _ in piles), piles      # more than any nominal pile's 3-8
    assert all(vox > 0 for _, _, vox in piles)
    nominal = []

    def policy_nominal(obs):
        if env.steps == 0:
            nominal.append((env.sim.material, env.sim.pile.rocks))
        return np.array([1.0, 1.0, 1.0])

    evaluate(env, policy_nominal, 8, 11, cfg["task"]["bucket_capacity"], breakdown=False)
    assert {m for m, _ in nominal} == {"homogeneous", "nonhomogeneous"}
    assert all(n <= cfg["pile"]["rocks_max"] for _, n in nominal)


def test_lhd_eval_refuses_actor_only_options_for_the_heuristic(capsys):
    from lhd_loading_ros.cli.main import main

    for opt in (["--randomize"], ["--stress", "delay"], ["--deploy-filter"]):
        assert main(["eval", "--controller", "tampier", *opt]) == 2
        assert "apply to --controller actor only" in capsys.readouterr().err


def test_rough_stress_case_gives_every_pile_a_relief_and_nominal_piles_stay_planes(cfg):
    """`--stress rough`: every evaluation pile's surface departs from its plane by about
    ROUGH_SD (the first step sees the intact surface; the attack drive cut only near the toe, so
    the back two thirds are compared); the nominal evaluation's piles are exact planes there, and a
    rough episode still runs to its end."""
    from lhd_loading_ros.learning.evaluate import evaluate
    from lhd_loading_ros.task.randomization import ROUGH_CORR, ROUGH_SD, stress_conditions

    c = stress_conditions("rough", 3, cfg)
    assert (c.surface_sd, c.surface_corr) == (ROUGH_SD, ROUGH_CORR) == (0.03, 0.15)
    env = LhdLoadingEnv("rld", cfg)
    seen = []

    def policy(obs):
        if env.steps == 0:
            p = env.sim.pile
            plane = np.tile(np.clip(p.x_centers * math.tan(p.alpha), 0.0, p.h), (p.n_y, 1))
            back = slice(p.n_x // 3, None)
            inner = (plane[:, back] > 0.1) & (plane[:, back] < p.h - 0.1)
            seen.append(float(np.std((p.top - plane)[:, back][inner])))
        return np.array([1.0, 1.0, 1.0])

    res = evaluate(env, policy, 8, 21, cfg["task"]["bucket_capacity"], breakdown=False, stress="rough")
    assert res["episodes"] == 8 and len(seen) == 8
    assert all(0.015 < s < 0.045 for s in seen), seen
    seen.clear()
    evaluate(env, policy, 4, 21, cfg["task"]["bucket_capacity"], breakdown=False)
    assert seen == [0.0] * 4


def test_on_a_rough_pile_the_policy_is_told_the_scanned_slices_slope(cfg):
    """A rough face's slope as the machine's LiDAR measures it is its XZ slice's (docs/perception.md
    "Rough faces"): the observation's alpha on a `rough` stress pile is the least-squares slope of
    the centre slice's column tops (computed here with numpy from the pile, between 3 cm above the
    floor and 3 cm below the crest), not the plane's; on a plane pile both are alpha."""
    from lhd_loading_ros.task.randomization import stress_conditions

    env = LhdLoadingEnv("rld", cfg)
    p = env.p
    differs = []
    for i in range(6):
        obs, _ = env.reset(seed=40 + i, options={"slope_deg": 20.0, "conditions": stress_conditions("rough", i, cfg)})
        pile = env.sim.pile
        j = int(np.argmin(np.abs(pile.y_centers)))
        top = pile.top0[j]
        face = (top > 0.03) & (top < pile.h - 0.03)
        own = math.atan(np.polyfit(pile.x_centers[face], top[face], 1)[0])
        told = p.alpha_min + float(obs[11]) * (p.alpha_max - p.alpha_min)
        assert told == pytest.approx(own, abs=1e-5), (math.degrees(told), math.degrees(own))
        differs.append(abs(math.degrees(own - pile.alpha)))
    assert max(differs) > 0.2                       # the relief really tilts the slices
    obs, _ = env.reset(seed=40, options={"slope_deg": 20.0})
    assert p.alpha_min + float(obs[11]) * (p.alpha_max - p.alpha_min) == pytest.approx(math.radians(20.0), abs=1e-6)
    assert env.sim.pile.slice_slope() == pytest.approx(math.radians(20.0), abs=1e-9)


def test_actuator_gains_scale_what_the_actuators_are_asked_for(cfg):
    """A drive gain g: the wheels' velocity servos get g times the command (the machine's wheels
    turn slower than the controller asked: a sagging battery, a speed loop off); a hydraulic gain
    h: boom and bucket move at h times the commanded rate. Gains of 1 are bit-identical to the
    nominal simulator. Over one period the unloaded boom (lifting out of the pile's reach, no FEE
    on it) travels about h times as far: the valve-limited rate, less the same start-up transient."""
    a, b = _pair(cfg, Conditions(drive_gain=1.0, hydraulic_gain=1.0))
    u = np.array([2.0, -0.191, 0.2])
    a.step(u)
    b.step(u)
    np.testing.assert_array_equal(_sim_state(a), _sim_state(b))
    c = LhdSimulator(cfg)       # the drive gain acts on the attack drive too: another start, so not _pair
    c.reset(np.random.default_rng(4), alpha=math.radians(20.0), material="homogeneous", d_attack=0.15,
            attack_speed=2.7, conditions=Conditions(drive_gain=0.8, hydraulic_gain=0.75))
    c.set_command(np.array([2.5, -0.191, 0.2]))
    assert [c.data.ctrl[k] for k in c._act_wheels] == [2.0] * len(c._act_wheels)
    assert c.data.ctrl[c.act_boom] == pytest.approx(-0.191 * 0.75) and c.data.ctrl[c.act_bucket] == pytest.approx(0.15)
    # the boom lifting from the attack pose for a second: travel ratio about 0.75
    a, b = _pair(cfg, Conditions(hydraulic_gain=0.75))
    q0a, q0b = float(a.data.qpos[a.boom_q]), float(b.data.qpos[b.boom_q])
    for _ in range(10):
        a.step(np.array([0.0, -0.191, 0.0]))
        b.step(np.array([0.0, -0.191, 0.0]))
    da, db = q0a - float(a.data.qpos[a.boom_q]), q0b - float(b.data.qpos[b.boom_q])
    assert da > 0.1 and 0.70 < db / da < 0.80, (da, db)


def test_actuator_gains_are_drawn_last_and_only_where_set(cfg):
    """`randomization.drive_gain_min/max`, `hydraulic_gain_min/max`: uniform per episode. With the
    ranges at (1, 1) (their defaults: off) nothing is drawn for them, so a run of earlier draws
    replays exactly; drawn after everything else, so episode 0's other conditions are the same."""
    import copy
    from dataclasses import replace

    from lhd_loading_ros.task.randomization import RandomizationRanges, draw

    on = copy.deepcopy(cfg)
    on["randomization"].update(enabled=1, drive_gain_min=0.8, drive_gain_max=1.1, hydraulic_gain_min=0.75,
                               hydraulic_gain_max=1.1)
    off = copy.deepcopy(cfg)
    off["randomization"]["enabled"] = 1
    rr_on, rr_off = RandomizationRanges.from_config(on), RandomizationRanges.from_config(off)
    assert rr_off.drive_gain == rr_off.hydraulic_gain == (1.0, 1.0)
    ra, rb = np.random.default_rng(7), np.random.default_rng(7)
    c_on, c_off = draw(ra, rr_on), draw(rb, rr_off)
    assert replace(c_on, drive_gain=1.0, hydraulic_gain=1.0) == c_off
    assert ra.bit_generator.state != rb.bit_generator.state          # two more numbers drawn
    rb.uniform(), rb.uniform()
    assert ra.bit_generator.state == rb.bit_generator.state          # exactly two
    cs = [draw(ra, rr_on) for _ in range(2000)]
    for name, lo, hi in (("drive_gain", 0.8, 1.1), ("hydraulic_gain", 0.75, 1.1)):
        v = np.array([getattr(c, name) for c in cs])
        assert lo <= v.min() < lo + 0.01 * (hi - lo) and hi - 0.01 * (hi - lo) < v.max() <= hi
        assert abs(v.mean() - 0.5 * (lo + hi)) < 0.03 * (hi - lo)
    assert all(c.drive_gain == 1.0 and c.hydraulic_gain == 1.0 for c in (draw(rb, rr_off) for _ in range(50)))


def test_cohesive_stress_case_reaches_the_voxels_and_stalls_the_push_sooner(cfg):
    """`--stress cohesive`: every pile's gravel at COHESIVE_PA (1,500 Pa, each voxel within the
    pile's +-5 % voxel spread) where the configured gravel is cohesionless, everything else drawn as
    in the nominal evaluation (the same generator draws: the same pile but for cohesion). Pushing
    with the arm still, the cohesive pile stalls the machine shallower: the drive's limit (4 x 30 N m
    / 0.137 m = 876 N) is reached with the lip less deep, since the wedge gains the term c d N_c."""
    from lhd_loading_ros.task.randomization import COHESIVE_PA, NOMINAL, SoilRanges, stress_conditions

    c = stress_conditions("cohesive", 5, cfg)
    assert COHESIVE_PA == 1500.0 and c.soil.cohesion == (1500.0, 1500.0)
    base = SoilRanges.from_config(cfg)
    assert base.cohesion == (0.0, 0.0)
    assert (c.soil.density, c.soil.phi, c.soil.rocks) == (base.density, base.phi, base.rocks)
    ends = {}
    for name, cond in (("nominal", NOMINAL), ("cohesive", c)):
        sim = LhdSimulator(cfg)
        sim.reset(np.random.default_rng(4), alpha=math.radians(20.0), material="homogeneous", d_attack=0.15,
                  attack_speed=2.7, conditions=cond)
        coh = sim.pile.cohesion
        for _ in range(15):                     # 1.5 s of full drive, arm still: both stall in the pile
            sim.step(np.array([2.7, 0.0, 0.0]))
        f = sim.last_fee
        ends[name] = (float(coh.min()), float(coh.max()), float(sim.data.site_xpos[sim.sid_tip][0]),
                      -float(f.force[0]), float(np.mean(f.depth)))
    (c0, c1, x_n, f_n, d_n), (k0, k1, x_c, f_c, d_c) = ends["nominal"], ends["cohesive"]
    assert c0 == c1 == 0.0
    assert 1500.0 * 0.95 - 1e-6 <= k0 < k1 <= 1500.0 * 1.05 + 1e-6
    drive_limit = 4 * cfg["machine"]["wheel_torque_limit"] / cfg["machine"]["wheel_radius"]
    assert f_n == pytest.approx(drive_limit, rel=0.1) and f_c == pytest.approx(drive_limit, rel=0.1)
    assert x_c < x_n - 0.05, ends               # stalled at least 5 cm short
    assert d_c < d_n - 0.02, ends               # with the lip at least 2 cm less deep


def test_a_slope_estimate_error_moves_the_zones_the_episode_is_observed_and_ended_with(cfg):
    """On the machine the end-zone node builds the zones from the LiDAR's slope: a 15 deg pile told
    45 deg gets the 45 deg wedge's zones, whose restricted zone starts at 0.68 / tan 45 - 0.1 =
    0.58 m, where the pile's own starts at 0.68 / tan 15 - 0.1 = 2.44 m. Pushing into it with the
    arm still ends the episode there as a failure (the supervisor's restricted zone); with the
    slope error in the observed alpha only (zones_from_estimate=False) the same push goes on past
    it. The observed d_end is measured to the estimate's x_max in both the reset and the steps."""
    told = Conditions(slope_error_deg=30.0)
    opts = dict(slope_deg=15.0, material="homogeneous", conditions=told, d_attack=0.15, attack_speed=2.7)
    est = LhdLoadingEnv("rld", cfg, zones_from_estimate=True)
    own = LhdLoadingEnv("rld", cfg, zones_from_estimate=False)
    oe, ie = est.reset(seed=3, options=opts)
    oo, io = own.reset(seed=3, options=opts)
    assert ie["zones_from"] == "estimate" and io["zones_from"] == "pile"
    pile_z = own.sim.zones
    k = math.sqrt(math.tan(math.radians(15)) / math.tan(math.radians(45)))
    # scaled by the wedge's ratio, at most the told wedge's depth (0.68 m at 45 deg)
    assert ie["x_max"] == pytest.approx(min(pile_z.x_max * k, 0.68)) and io["x_max"] == pile_z.x_max
    assert est.zones.x_cutoff == pytest.approx(0.68 - 0.1) and pile_z.x_cutoff == pytest.approx(0.68 / math.tan(
        math.radians(15)) - 0.1)
    p = est.p
    x = est.state.x_shovel
    assert oe[10] == pytest.approx(abs(x - ie["x_max"]) / p.d_end_max, abs=1e-6)
    assert oo[10] == pytest.approx(abs(x - pile_z.x_max) / p.d_end_max, abs=1e-6)
    np.testing.assert_array_equal(np.delete(oe, 10), np.delete(oo, 10))   # the rest is the same sensor reading
    push = np.array([2.7, 0.0, 0.0])            # rad/s: full wheel speed, boom and bucket still
    ends = {}
    for name, env in (("est", est), ("own", own)):
        for k_step in range(60):
            obs, r, term, trunc, info = env.step_actuator(push)
            if term or trunc:
                break
        ends[name] = (info["outcome"], env.state.x_shovel, k_step)
    # judged at the end of a 0.1 s period: past the limit by at most a period's travel (0.37 m/s)
    assert ends["est"][0] == "failure" and 0.58 <= ends["est"][1] < 0.58 + 0.04, ends
    assert ends["own"][0] == "running" and ends["own"][1] > 0.62, ends


def test_an_estimate_outside_the_lidars_range_leaves_the_piles_zones(cfg):
    """A 15 deg pile told 0 deg: the end-zone node publishes nothing (the attempt would not start on
    the machine); the simulated episode keeps the pile's zones and says so."""
    env = LhdLoadingEnv("rld", cfg, zones_from_estimate=True)
    _, info = env.reset(seed=3, options=dict(slope_deg=15.0, conditions=Conditions(slope_error_deg=-15.0)))
    assert info["zones_from"] == "pile, estimate out of range" and info["x_max"] == env.sim.zones.x_max


def test_a_start_from_rest(cfg):
    """`Conditions.rest_start` (`lhd eval --stress rest`, `randomization.rest_start_share`): after the drive
    in, the machine stops with the tip in the pile, as an attempt on the machine starts. Against the same
    pile, start distance and attack speed without it: the paper's episode starts at the attack speed."""
    from lhd_loading_ros.task.randomization import stress_conditions

    fixed = dict(alpha=math.radians(20.0), material="homogeneous", d_attack=0.15, attack_speed=2.7)
    a, b = LhdSimulator(cfg), LhdSimulator(cfg)
    a.reset(np.random.default_rng(4), **fixed)
    b.reset(np.random.default_rng(4), conditions=stress_conditions("rest", 0, cfg), **fixed)
    r = a.wheel_radius
    assert a.state().v_x > 0.2                                   # hits the pile moving
    sb = b.state()
    assert abs(sb.v_x) < 0.005 and float(np.max(np.abs(b.wheel_speeds()))) * r < 0.005
    assert sb.x_shovel >= a.state().x_shovel >= a.p.d_init        # it coasted a little further in
    assert (sb.drift_front, sb.drift_rear) == (False, False)      # standing: no slip over the last period
    assert b.loaded_mass >= a.loaded_mass >= 0.0
    # full wheels from rest: the machine moves off, no faster than its motors can push it. By hand: four
    # wheel motors at machine.wheel_torque_limit on wheels of radius r accelerate the machine's mass at
    # most 4 tau / (r m) (the pile only holds it back), so v_x <= that x one period
    m_total = float(sum(b.model.body_mass))
    a_max = 4.0 * cfg["machine"]["wheel_torque_limit"] / (r * m_total)
    b.step(np.array([2.7, 0.0, 0.0]))
    assert 0.1 < b.state().v_x <= a_max * 0.1, (b.state().v_x, a_max)
    # the stress case changes nothing else
    assert stress_conditions("rest", 5, cfg) == Conditions(rest_start=True)


def test_starts_from_rest_are_drawn_last_and_only_where_set(cfg):
    import copy
    from dataclasses import replace

    from lhd_loading_ros.task.config import ConfigError, config_hash, validate
    from lhd_loading_ros.task.randomization import RandomizationRanges, draw

    on = copy.deepcopy(cfg)
    on["randomization"].update(enabled=1, rest_start_share=0.25)
    off = copy.deepcopy(cfg)
    off["randomization"]["enabled"] = 1
    rr_on, rr_off = RandomizationRanges.from_config(on), RandomizationRanges.from_config(off)
    assert rr_off.rest_start_share == 0.0 and rr_on.rest_start_share == 0.25
    ra, rb = np.random.default_rng(7), np.random.default_rng(7)
    c_on, c_off = draw(ra, rr_on), draw(rb, rr_off)
    assert replace(c_on, rest_start=False) == c_off
    rb.random()
    assert ra.bit_generator.state == rb.bit_generator.state          # exactly one more number drawn
    share = np.mean([draw(ra, rr_on).rest_start for _ in range(4000)])
    assert abs(share - 0.25) < 0.03
    assert not any(draw(rb, rr_off).rest_start for _ in range(200))
    # the share is a training setting: at 0 it leaves the hash as it was; the key is checked
    assert config_hash(off) == config_hash({**off, "randomization": {k: v for k, v in off["randomization"].items()
                                                                      if k != "rest_start_share"}})
    assert config_hash(on) != config_hash(off)
    bad = copy.deepcopy(cfg)
    bad["randomization"]["rest_start_share"] = 1.5
    with pytest.raises(ConfigError, match="rest_start_share"):
        validate(bad)


def test_a_surface_relief_is_drawn_last_and_only_where_set(cfg):
    """`randomization.surface_sd_max` (2026-11-29): each training pile's relief sd U(0, max), with the
    rough stress case's correlation length; drawn after every other value, so a file without it draws
    what it drew before; at 0 out of the hash; in the environment the drawn pile is rough (its std
    about the plane, measured here with numpy, near the drawn sd) and a plane where none is drawn."""
    import copy
    from dataclasses import replace

    from lhd_loading_ros.task.config import ConfigError, config_hash, validate
    from lhd_loading_ros.task.randomization import ROUGH_CORR, RandomizationRanges, draw

    on = copy.deepcopy(cfg)
    on["randomization"].update(enabled=1, surface_sd_max=0.03)
    off = copy.deepcopy(cfg)
    off["randomization"]["enabled"] = 1
    rr_on, rr_off = RandomizationRanges.from_config(on), RandomizationRanges.from_config(off)
    assert rr_off.surface_sd_max == 0.0 and rr_on.surface_sd_max == 0.03
    ra, rb = np.random.default_rng(11), np.random.default_rng(11)
    c_on, c_off = draw(ra, rr_on), draw(rb, rr_off)
    assert 0.0 <= c_on.surface_sd <= 0.03 and c_on.surface_corr == ROUGH_CORR == 0.15
    assert replace(c_on, surface_sd=0.0) == c_off
    rb.uniform()
    assert ra.bit_generator.state == rb.bit_generator.state          # exactly one more number drawn
    sds = [draw(ra, rr_on).surface_sd for _ in range(4000)]
    assert min(sds) >= 0.0 and max(sds) <= 0.03 and abs(np.mean(sds) - 0.015) < 0.001   # U(0, 0.03)
    assert all(draw(rb, rr_off).surface_sd == 0.0 for _ in range(200))
    assert config_hash(off) == config_hash({**off, "randomization": {k: v for k, v in off["randomization"].items()
                                                                      if k != "surface_sd_max"}})
    assert config_hash(on) != config_hash(off)
    bad = copy.deepcopy(cfg)
    bad["randomization"]["surface_sd_max"] = -0.01
    with pytest.raises(ConfigError, match="surface_sd_max"):
        validate(bad)
    # in the environment: a drawn relief of 3 cm is rough about the plane, a drawn 0 a plane
    env = LhdLoadingEnv("rld", cfg)
    for sd in (0.03, 0.0):
        env.reset(seed=5, options={"slope_deg": 20.0, "material": "homogeneous",
                                   "conditions": replace(c_off, surface_sd=sd, surface_corr=ROUGH_CORR,
                                                         slope_error_deg=0.0)})
        p = env.sim.pile
        plane = np.tile(np.clip(p.x_centers * math.tan(p.alpha), 0.0, p.h), (p.n_y, 1))
        back = slice(p.n_x // 3, None)
        inner = (plane[:, back] > 0.1) & (plane[:, back] < p.h - 0.1)
        dev = float(np.std((p.top - plane)[:, back][inner]))
        assert (0.015 < dev < 0.045) if sd else dev == pytest.approx(0.0, abs=1e-9), (sd, dev)


def test_an_actor_randomised_on_plane_piles_runs_on_a_file_with_a_relief_and_back(cfg):
    """As for the starts from rest: an actor trained randomised before `surface_sd_max` existed (the key
    absent: 0) matches a parameter file that sets a relief; one trained with a relief matches its own
    file, and the file with the relief at 0 (the section's other ranges the same)."""
    import copy

    from lhd_loading_ros.task.config import config_hash, hash_matches

    old = copy.deepcopy(cfg)
    old["randomization"]["enabled"] = 1
    del old["randomization"]["surface_sd_max"]
    rough = copy.deepcopy(cfg)
    rough["randomization"]["surface_sd_max"] = 0.03
    assert hash_matches(config_hash(old), rough) and hash_matches(config_hash(old), cfg)
    trained = copy.deepcopy(rough)
    trained["randomization"]["enabled"] = 1
    assert hash_matches(config_hash(trained), rough)
    other = copy.deepcopy(trained)
    other["randomization"]["surface_sd_max"] = 0.05     # another relief: another actor's file
    assert not hash_matches(config_hash(other), rough)


def test_an_actor_randomised_before_starts_from_rest_runs_on_a_file_that_has_them(cfg):
    """An actor trained randomised before `rest_start_share` existed (the key absent: 0) matches a
    parameter file that sets a share, as it matches one with the share at 0; one trained with a share
    matches the file that has it."""
    import copy

    from lhd_loading_ros.task.config import config_hash, hash_matches

    old = copy.deepcopy(cfg)
    old["randomization"]["enabled"] = 1
    del old["randomization"]["rest_start_share"]
    with_rest = copy.deepcopy(cfg)
    with_rest["randomization"]["rest_start_share"] = 0.25
    assert hash_matches(config_hash(old), with_rest) and hash_matches(config_hash(old), cfg)
    trained = copy.deepcopy(with_rest)
    trained["randomization"]["enabled"] = 1
    assert hash_matches(config_hash(trained), with_rest)


def test_the_machine_stress_case_is_placement_from_rest_on_a_rough_pile(cfg):
    """`--stress machine`: how an attempt on the machine goes, all at once: placed by hand (each
    corner of `placement`, with its camera errors and dead time), from rest (`rest`) and on a pile whose
    surface is no plane (`rough`); nothing else. In the environment the episode starts standing, off
    the pile's axis, on a relief, and the observed slope is the scanned slice's."""
    from dataclasses import replace

    from lhd_loading_ros.task.randomization import ROUGH_CORR, ROUGH_SD, stress_conditions

    for i in (0, 8, 16, 24):
        m, place = stress_conditions("machine", i, cfg), stress_conditions("placement", i, cfg)
        assert m == replace(place, rest_start=True, surface_sd=ROUGH_SD, surface_corr=ROUGH_CORR)
        assert m.rest_start and m.surface_sd == 0.03 and abs(m.heading_deg) == 3.0 and abs(m.lateral_offset) == 0.05
        assert m.drive_delay_s == m.hydraulic_delay_s == 0.1 and m.soil is None and m.slope_error_deg == 0.0
    env = LhdLoadingEnv("rld", cfg)
    env.reset(seed=3, options={"slope_deg": 20.0, "material": "homogeneous",
                               "conditions": stress_conditions("machine", 0, cfg)})
    sim = env.sim
    assert abs(sim.state().v_x) < 0.005                         # standing
    p = sim.pile                                                # a relief: the back two thirds off the plane
    plane = np.tile(np.clip(p.x_centers * math.tan(p.alpha), 0.0, p.h), (p.n_y, 1))
    back = slice(p.n_x // 3, None)
    inner = (plane[:, back] > 0.1) & (plane[:, back] < p.h - 0.1)
    assert 0.015 < float(np.std((p.top - plane)[:, back][inner])) < 0.045
    w, x, y, z = sim.data.qpos[3:7]                             # the heading kept from the placement
    assert math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))) == pytest.approx(3.0, abs=0.3)


def test_the_end_zone_nodes_zones_do_not_know_the_piles_density(cfg):
    """zones_nominal_density: the zones are the end-zone node's wedge at the config's nominal density
    (1,880 kg/m^3), as on the machine, so a light pile (1,500 kg/m^3) and a dense one (2,200) get the
    same end zone: on a 20 deg pile x_max = sqrt(2 x 170 / (1880 x 0.4 x tan 20)) = 1.114545 m by hand.
    The pile's own end zone follows its density (x ~ 1 / sqrt(rho)): farther on the light pile,
    nearer on the dense one. A slope error moves the node's zones to the estimate's wedge (15 deg
    pile told 30 deg: x_max 0.884934 m by hand), and d_end is measured to them."""
    from dataclasses import replace as _replace

    from lhd_loading_ros.task.randomization import SoilRanges

    base = SoilRanges.from_config(cfg)
    node = LhdLoadingEnv("rld", cfg, zones_from_estimate=True, zones_nominal_density=True)
    own = LhdLoadingEnv("rld", cfg, zones_from_estimate=True, zones_nominal_density=False)
    xs = {}
    for rho in (1500.0, 2200.0):
        c = Conditions(soil=_replace(base, density=(rho, rho)))
        opts = dict(slope_deg=20.0, material="homogeneous", conditions=c)
        _, i_node = node.reset(seed=5, options=opts)
        _, i_own = own.reset(seed=5, options=opts)
        assert float(np.median(node.sim.pile.density[node.sim.pile.density > 0])) == pytest.approx(rho, rel=0.01)
        assert i_node["zones_from"] == "wedge at nominal density" and i_own["zones_from"] == "pile"
        assert i_node["x_max"] == pytest.approx(1.114545, abs=2e-6)
        xs[rho] = i_own["x_max"]
    # the pile's own: where its own 170 kg lie (a voxel's grain, 2 cm, about the wedge's figure)
    assert xs[1500.0] == pytest.approx(1.114545 * math.sqrt(1880 / 1500), abs=0.02)
    assert xs[2200.0] == pytest.approx(1.114545 * math.sqrt(1880 / 2200), abs=0.02)
    # the node's `density` set to a light material's (zones_density): x_max = 1.114545 x sqrt(1880 / 1550)
    # = 1.227469 m by hand, on any pile
    light = LhdLoadingEnv("rld", cfg, zones_from_estimate=True, zones_nominal_density=True, zones_density=1550.0)
    _, i_light = light.reset(seed=5, options=dict(slope_deg=20.0, material="homogeneous"))
    assert i_light["x_max"] == pytest.approx(1.227469, abs=2e-6)
    with pytest.raises(ValueError, match="zones_density: bulk density 3.2 kg/m\\^3 outside"):
        LhdLoadingEnv("rld", cfg, zones_nominal_density=True, zones_density=3.2)
    told = Conditions(slope_error_deg=15.0)
    obs, info = node.reset(seed=5, options=dict(slope_deg=15.0, material="homogeneous", conditions=told))
    assert info["x_max"] == pytest.approx(0.884934, abs=2e-6) and node.zones.x_cutoff == pytest.approx(
        0.68 / math.tan(math.radians(30)) - 0.1)
    assert obs[10] == pytest.approx(abs(node.state.x_shovel - 0.884934) / node.p.d_end_max, abs=1e-6)


def test_the_nominal_density_zones_come_from_the_config_key(cfg):
    """randomization.zones_at_nominal_density (0 / 1) sets the training environment's zones where the
    section is on, as the config hash has the key only then: with the section off (a shipped parameter
    file, the sim node) the pile's own zones judge, whatever the key says. 0 leaves the config hash as it
    was, so actors trained before the key still load; 2 is refused."""
    from lhd_loading_ros.task.config import ConfigError, config_hash, validate

    on = {**cfg, "randomization": {**cfg["randomization"], "zones_at_nominal_density": 1, "enabled": 1}}
    assert LhdLoadingEnv("rld", on).zones_nominal_density is True
    assert LhdLoadingEnv("rld", cfg).zones_nominal_density is False
    off = {**cfg, "randomization": {**cfg["randomization"], "zones_at_nominal_density": 1, "enabled": 0}}
    env = LhdLoadingEnv("rld", off)
    assert env.zones_nominal_density is False and config_hash(off) == config_hash(cfg)
    _, info = env.reset(seed=5, options=dict(slope_deg=20.0, material="homogeneous"))
    assert info["zones_from"] == "pile" and info["x_max"] == env.sim.zones.x_max
    assert LhdLoadingEnv("rld", off, zones_nominal_density=True).zones_nominal_density is True   # asked for
    rand = {**cfg, "randomization": {**cfg["randomization"], "enabled": 1}}
    rand0 = {**rand, "randomization": {**rand["randomization"], "zones_at_nominal_density": 0}}
    rand1 = {**rand, "randomization": {**rand["randomization"], "zones_at_nominal_density": 1}}
    without = {**rand, "randomization": {k: v for k, v in rand["randomization"].items()
                                         if k != "zones_at_nominal_density"}}
    assert config_hash(rand0) == config_hash(without) != config_hash(rand1)
    bad = {**cfg, "randomization": {**cfg["randomization"], "zones_at_nominal_density": 2}}
    with pytest.raises(ConfigError, match="zones_at_nominal_density"):
        validate(bad)


def test_training_through_the_sim_nodes_refuses_the_end_zone_nodes_zones(cfg, tmp_path):
    """The sim nodes judge and publish the pile's own zones: `lhd train --env ros` with
    randomization.zones_at_nominal_density = 1 (and the section on) is refused before anything starts,
    naming the key."""
    import copy

    from lhd_loading_ros.learning.train import train

    c = copy.deepcopy(cfg)
    c["randomization"].update(enabled=1, zones_at_nominal_density=1)
    with pytest.raises(ValueError, match="zones_at_nominal_density = 1 .* needs the in-process environment"):
        train("rld", 0, tmp_path, steps=10, config=c, resume=False, progress=False, env_kind="ros",
              namespaces=["/sim0"])


def _mujoco_tip_at(env, boom_offset_deg: float, bucket_offset_deg: float):
    """(x, z, pitch) of the tip site by MuJoCo's own forward kinematics, at the machine's true pose with the
    boom and bucket joints turned by the offsets: an independent route to where the measured angles put it."""
    import mujoco

    sim = env.sim
    d = mujoco.MjData(sim.model)
    d.qpos[:] = sim.data.qpos
    d.qpos[sim.boom_q] += math.radians(boom_offset_deg)
    d.qpos[sim.bucket_q] += math.radians(bucket_offset_deg)
    mujoco.mj_kinematics(sim.model, d)
    xm = d.site_xmat[sim.sid_tip]
    return float(d.site_xpos[sim.sid_tip][0]), float(d.site_xpos[sim.sid_tip][2]), math.atan2(xm[6], xm[0])


def test_arm_angle_sensor_offsets_move_the_measured_tip_as_mujoco_puts_it(cfg):
    """Conditions.boom_offset_deg / bucket_offset_deg (2026-11-29): the boom and bucket angles read off their
    true values; the measured tip and pitch (observation, heuristic, end test) are where MuJoCo's forward
    kinematics puts the tip with the joints at the measured angles, from the machine's true pose; the pitch
    moves by exactly bucket - boom (the bucket curls the tip frame back, the boom lowers it). The true state,
    the physics and the load do not change. Without offsets the measured state is the true one."""
    env = LhdLoadingEnv("rld", cfg)
    opts = {"slope_deg": 25.0, "material": "homogeneous", "d_attack": 0.15, "attack_speed": 2.7}
    env.reset(seed=3, options={**opts, "conditions": NOMINAL})
    assert env.measured_state is env.state
    plain = [env.step(np.array([0.6, -0.4, 0.5]))[0] for _ in range(8)]
    true_plain = env.state
    for db, dk in ((2.0, 0.0), (0.0, -2.0), (-1.5, 2.5)):
        env.reset(seed=3, options={**opts, "conditions": Conditions(boom_offset_deg=db, bucket_offset_deg=dk)})
        obs = [env.step(np.array([0.6, -0.4, 0.5]))[0] for _ in range(8)]
        s, m = env.state, env.measured_state
        assert (s.x_shovel, s.z_shovel, s.phi_shovel) == (true_plain.x_shovel, true_plain.z_shovel,
                                                          true_plain.phi_shovel)    # the machine moved as before
        x, z, pitch = _mujoco_tip_at(env, db, dk)
        assert m.x_shovel == pytest.approx(x, abs=1e-6) and m.z_shovel == pytest.approx(z, abs=1e-6), (db, dk)
        assert m.phi_shovel == pytest.approx(pitch, abs=1e-9)
        assert m.phi_shovel - s.phi_shovel == pytest.approx(math.radians(dk - db), abs=1e-12)
        assert m.phi_boom - s.phi_boom == pytest.approx(math.radians(db)) and m.dphi_boom == s.dphi_boom
        # a boom turned by db moves the tip on a circle about the boom's axis: by 2 r sin(db / 2), r the tip's
        # distance from that axis (MuJoCo's joint anchor and axis)
        if dk == 0.0:
            jb = env.sim.model.joint("boom").id
            rel = env.sim.data.site_xpos[env.sim.sid_tip] - env.sim.data.xanchor[jb]
            axis = env.sim.data.xaxis[jb]
            r = float(np.linalg.norm(rel - rel.dot(axis) * axis))
            moved = math.hypot(m.x_shovel - s.x_shovel, m.z_shovel - s.z_shovel)
            assert 0.5 < r < 1.5 and moved == pytest.approx(2 * r * math.sin(math.radians(db) / 2), rel=1e-3), (r, moved)
        assert not np.allclose(obs[-1], plain[-1])                      # the policy sees the measured tip


def test_the_end_test_reads_the_measured_tip(cfg):
    """The supervisor ends an attempt when the tip its sensors give reaches the end zone: with the boom's sensor
    reading 3 deg low (lowered), the same commands (the physics are the offsets' none) end the episode later, with
    the true tip higher above z_min than without; in both, the measured tip is in the end zone at the end."""
    from lhd_loading_ros.task.zones import classify

    env = LhdLoadingEnv("rld", cfg)
    opts = {"slope_deg": 20.0, "material": "homogeneous", "d_attack": 0.15, "attack_speed": 2.7}
    ends = {}
    for db in (0.0, 3.0):
        env.reset(seed=8, options={**opts, "conditions": Conditions(boom_offset_deg=db)})
        for k in range(200):
            a = np.array([1.0, 1.0, -1.0]) if k < 14 else np.array([0.0, -1.0, 1.0])   # push, then stop, lift, curl
            _, _, term, trunc, info = env.step(a)
            if term or trunc:
                break
        assert info["outcome"] == "success", (db, info["outcome"], k)
        m = env.measured_state
        assert classify(m.x_shovel, m.y_shovel, m.z_shovel, env.zones) == "end"
        ends[db] = (k, env.state.z_shovel)
    assert ends[3.0][0] > ends[0.0][0] and ends[3.0][1] > ends[0.0][1] + 0.02, ends


def test_the_calibration_stress_case_and_the_drawn_offsets(cfg):
    """`lhd eval --stress calibration`: +-2 deg on the boom and on the bucket, every sign pair in 8 of every 32
    episodes, each pair on every slope and material of the stratified set; `randomization.arm_offset_max_deg`
    draws each offset U(-max, max) after every other value, so a file without it draws what it drew before."""
    import copy
    from dataclasses import replace

    from lhd_loading_ros.learning.evaluate import episode_conditions
    from lhd_loading_ros.task.randomization import CALIBRATION_OFFSET_DEG, RandomizationRanges, draw, stress_conditions

    assert CALIBRATION_OFFSET_DEG == 2.0
    cells: dict = {}
    for i in range(32):
        c = stress_conditions("calibration", i, cfg)
        assert replace(c, boom_offset_deg=0.0, bucket_offset_deg=0.0) == NOMINAL
        _, o = episode_conditions(i, 0)
        cells.setdefault((c.boom_offset_deg, c.bucket_offset_deg), set()).add((o["slope_deg"], o["material"]))
    assert set(cells) == {(2.0, 2.0), (-2.0, 2.0), (2.0, -2.0), (-2.0, -2.0)}
    assert all(len(v) == 8 for v in cells.values())                    # 4 slopes x 2 materials each
    on, off = copy.deepcopy(cfg), copy.deepcopy(cfg)
    on["randomization"].update(enabled=1, arm_offset_max_deg=2.5)
    off["randomization"]["enabled"] = 1
    ra, rb = np.random.default_rng(5), np.random.default_rng(5)
    c_on, c_off = draw(ra, RandomizationRanges.from_config(on)), draw(rb, RandomizationRanges.from_config(off))
    assert replace(c_on, boom_offset_deg=0.0, bucket_offset_deg=0.0) == c_off
    rb.uniform(), rb.uniform()
    assert ra.bit_generator.state == rb.bit_generator.state          # exactly two more numbers drawn
    offs = np.array([(c.boom_offset_deg, c.bucket_offset_deg)
                     for c in (draw(ra, RandomizationRanges.from_config(on)) for _ in range(3000))])
    assert np.abs(offs).max() <= 2.5 and np.abs(offs.mean(axis=0)).max() < 0.1
    assert abs(np.corrcoef(offs.T)[0, 1]) < 0.06                       # two draws, not one


def test_arm_angles_read_in_counts_give_the_firmwares_rates(cfg):
    """Conditions.arm_encoder_counts (2026-11-29): each step the boom and bucket angles are read in whole counts of
    the true angles, and the rates the policy sees are the firmware's: the difference of those readings over its
    0.1 s window (task/arm_sensors.py), here the reading one control period back, computed in the test from the true
    angles; the tip follows the read angles (the offsets' kinematics). The machine moves as without the sensors."""
    from lhd_loading_ros.task.arm_sensors import RATE_WINDOW_S

    assert RATE_WINDOW_S == LhdLoadingEnv("rld", cfg).p.control_dt == 0.1
    counts = 1024                                       # coarse: 6.1 mrad a count, so the reading visibly differs
    q = 2 * math.pi / counts
    env = LhdLoadingEnv("rld", cfg)
    opts = {"slope_deg": 20.0, "material": "homogeneous", "d_attack": 0.15, "attack_speed": 2.7}
    actions = [np.array([0.8, -0.6, 0.7])] * 6 + [np.array([0.2, -1.0, 1.0])] * 6
    env.reset(seed=4, options={**opts, "conditions": NOMINAL})
    truth = [env.state]
    for a in actions:
        env.step(a)
        truth.append(env.state)
    env.reset(seed=4, options={**opts, "conditions": Conditions(arm_encoder_counts=counts)})
    read = [env.measured_state]
    for a in actions:
        env.step(a)
        read.append(env.measured_state)
    boom_speed = max(abs(env.p.boom_min), abs(env.p.boom_max))
    moved = 0
    for k, (s, m) in enumerate(zip(truth, read)):
        assert env.state is not m
        for name in ("boom", "bucket"):
            true = getattr(s, "phi_" + name)
            count = round(true / q)
            assert getattr(m, "phi_" + name) == pytest.approx(count * q, abs=1e-12) and abs(count * q - true) <= q / 2
            if k > 0:
                back = round(getattr(truth[k - 1], "phi_" + name) / q) * q
                want = (count * q - back) / 0.1
                assert getattr(m, "dphi_" + name) == pytest.approx(want, abs=1e-9), (k, name)
                moved += want != 0.0
    assert moved >= 12                                     # the arm moved: the rates are not all zero
    assert read[-1].z_shovel != truth[-1].z_shovel and read[-1].x_shovel == pytest.approx(truth[-1].x_shovel, abs=0.01)
    obs = env._obs(read[-1])
    assert obs[7] == pytest.approx(np.clip(read[-1].dphi_boom / boom_speed, -1, 1), abs=1e-6)
    # with a calibration offset the sensor reads the true angle plus the offset, in counts
    env.reset(seed=4, options={**opts, "conditions": Conditions(boom_offset_deg=2.0, arm_encoder_counts=counts)})
    for a in actions[:3]:
        env.step(a)
    m, s = env.measured_state, env.state
    assert m.phi_boom == pytest.approx(round((s.phi_boom + math.radians(2.0)) / q) * q, abs=1e-12)
    assert m.phi_bucket == pytest.approx(round(s.phi_bucket / q) * q, abs=1e-12)


def test_noise_on_the_arm_angles_reaches_the_rates_as_sqrt2_sd_over_the_window(cfg):
    """Conditions.arm_angle_noise_deg: a machine standing in the pile with its arm still reads its angles with the
    noise's sd and its rates with sqrt(2) sd / 0.1 s (the firmware's window); 1 deg of noise, 200 steps."""
    env = LhdLoadingEnv("rld", cfg)
    opts = {"slope_deg": 30.0, "material": "homogeneous", "d_attack": 0.15, "attack_speed": 2.7}
    env.reset(seed=2, options={**opts, "conditions": Conditions(arm_angle_noise_deg=1.0)})
    errs, rates, true_rates = [], [], []
    for _ in range(200):
        _, _, term, trunc, _ = env.step_actuator(np.zeros(3))          # stopped, the arm held
        errs.append(env.measured_state.phi_boom - env.state.phi_boom)
        rates.append(env.measured_state.dphi_bucket)
        true_rates.append(env.state.dphi_bucket)
        if term or trunc:
            break
    rates, true_rates = rates[10:], true_rates[10:]      # after the bucket has settled
    assert len(errs) == 200 and max(map(abs, true_rates)) < 1e-3
    sd = math.radians(1.0)
    assert np.std(errs) == pytest.approx(sd, rel=0.2) and abs(np.mean(errs)) < 0.3 * sd
    assert np.std(rates) == pytest.approx(math.sqrt(2) * sd / 0.1, rel=0.2)


def test_the_arm_noise_stress_case_and_bad_sensor_conditions(cfg):
    from dataclasses import replace

    from lhd_loading_ros.task.randomization import ARM_ENCODER_COUNTS, ARM_NOISE_DEG, STRESS_CASES, stress_conditions

    assert "arm_noise" in STRESS_CASES and (ARM_NOISE_DEG, ARM_ENCODER_COUNTS) == (0.1, 4096)
    c = stress_conditions("arm_noise", 5, cfg)
    assert replace(c, arm_angle_noise_deg=0.0, arm_encoder_counts=0) == NOMINAL and c.arm_encoder_counts == 4096
    env = LhdLoadingEnv("rld", cfg)
    for bad in (Conditions(arm_angle_noise_deg=float("nan")), Conditions(arm_angle_noise_deg=-0.1),
                Conditions(arm_encoder_counts=-4), Conditions(arm_encoder_counts=40.5)):
        with pytest.raises(ValueError, match="arm_angle_noise_deg .* arm_encoder_counts"):
            env.reset(seed=0, options={"conditions": bad})
    env.reset(seed=0, options={"conditions": Conditions(arm_encoder_counts=np.int64(4096))})   # any whole number
