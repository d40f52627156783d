"""The parameter file: the paper's table is all there, and bad files fail naming the key."""
import copy

import pytest
import yaml

from lhd_loading_ros.task.config import ConfigError, default_config_path, load_config, validate

# Every row of the paper's table "Problem formulation parameters".
PAPER_TABLE = {
    ("ddpg", "actor_lr"): 0.0001, ("ddpg", "critic_lr"): 0.001, ("ddpg", "gamma"): 0.99,
    ("ddpg", "replay_size"): 200000, ("ddpg", "batch_size"): 256, ("ddpg", "tau"): 0.001,
    ("ddpg", "ou_mu"): 0.0, ("ddpg", "ou_sigma"): 0.4, ("ddpg", "ou_theta"): 0.15, ("ddpg", "ou_dt"): 0.2,
    ("reward", "R_zone"): 2000, ("reward", "R_traj"): 60, ("reward", "R_drift"): 5, ("reward", "R_bottom"): 5,
    ("reward", "R_midgoal"): 25, ("reward", "d_midgoal_max"): 0.44, ("reward", "R_stuck"): 5,
    ("reward", "T_stuck"): 8, ("reward", "delta_thresh"): 0.005, ("reward", "R_inact"): 50,
    ("reward", "u_thresh_boom"): 0.5, ("reward", "u_thresh_bucket"): 0.5, ("reward", "R_weight"): 1,
    ("reward", "R_dump"): 20, ("reward", "phi_thresh_pitch_deg"): 40, ("reward", "R_success"): 40,
    ("reward", "W_target"): 30, ("reward", "phi_target_deg"): 40, ("reward", "rho_thresh_W"): 1,
    ("reward", "rho_thresh_phi_deg"): 5,
    ("observation", "d_end_max"): 0.87, ("observation", "x_init_obs"): 0.1, ("observation", "x_obs"): 1.1,
    ("observation", "y_obs"): 0.4, ("observation", "z_obs"): 0.4,
    ("control", "frequency_hz"): 10, ("control", "wheels_min"): 0, ("control", "wheels_max"): 2.7,
    ("control", "boom_min"): -0.191, ("control", "boom_max"): 0, ("control", "bucket_min"): 0,
    ("control", "bucket_max"): 0.2,
    ("voxels", "n_x"): 60, ("voxels", "n_y"): 7, ("voxels", "n_z"): 10,
    ("end_zone", "m_min"): 65, ("end_zone", "m_max"): 170, ("end_zone", "z_min"): 0.35,
    ("episode", "h_pile"): 0.68, ("episode", "w_pile"): 0.4, ("episode", "alpha_min_deg"): 15,
    ("episode", "alpha_max_deg"): 30, ("episode", "d_attack_min"): 0.1, ("episode", "d_attack_max"): 0.2,
    ("episode", "d_init"): 0.1, ("episode", "max_steps"): 200,
}


def test_default_file_holds_the_paper_table():
    cfg = load_config()
    for (section, key), value in PAPER_TABLE.items():
        assert cfg["paper"][section][key] == pytest.approx(value), f"paper.{section}.{key}"
    assert default_config_path().name == "lhd_params.yaml"


def test_missing_key_is_named(cfg):
    del cfg["paper"]["reward"]["R_zone"]
    with pytest.raises(ConfigError, match=r"missing key 'paper\.reward\.R_zone' \(expected float in \[0, 1e\+06\]\)"):
        validate(cfg)


def test_misspelt_key_is_named_with_a_suggestion(cfg):
    cfg["paper"]["reward"]["R_zon"] = cfg["paper"]["reward"].pop("R_zone")
    with pytest.raises(ConfigError) as exc:
        validate(cfg)
    msg = str(exc.value)
    assert "unknown key 'paper.reward.R_zon' (did you mean 'R_zone'?)" in msg
    assert "missing key 'paper.reward.R_zone'" in msg


def test_out_of_range_names_key_and_range(cfg):
    cfg["paper"]["ddpg"]["gamma"] = 1.5
    with pytest.raises(ConfigError, match=r"'paper\.ddpg\.gamma' = 1\.5 is out of range; expected float in \[0, 0\.9999\]"):
        validate(cfg)


def test_wrong_type_and_non_integer(cfg):
    cfg["paper"]["voxels"]["n_x"] = 60.5
    cfg["machine"]["wheel_radius"] = "big"
    with pytest.raises(ConfigError) as exc:
        validate(cfg)
    assert "'paper.voxels.n_x' = 60.5 must be an integer" in str(exc.value)
    assert "'machine.wheel_radius' = 'big' is not a number" in str(exc.value)


def test_relations_between_keys(cfg):
    cfg["paper"]["end_zone"]["m_min"] = 200.0
    with pytest.raises(ConfigError, match="m_min < paper.end_zone.m_max"):
        validate(cfg)


@pytest.mark.parametrize("section, key, value, needle", [
    ("paper.control", "frequency_hz", 20.0, "sim.timestep divides the control period"),   # 0.05 / 0.004 = 12.5
    ("sim", "timestep", 0.03, "sim.timestep divides the control period"),                  # 0.1 / 0.03 = 3.33
    ("sim", "fee_every", 3, "sim.fee_every divides the physics steps"),                    # 25 % 3 = 1
])
def test_the_simulators_step_relations_are_checked_with_the_file(cfg, section, key, value, needle):
    """A file the simulator would refuse with a traceback (a review: `lhd config check` said ok,
    `lhd eval` then failed inside the simulator) is refused by the config's own check; the default
    (0.004 s, 25 steps of 0.1 s, FEE every 5) passes, and so do 20 Hz with 0.005 s and FEE every 10."""
    node = cfg
    for part in section.split("."):
        node = node[part]
    node[key] = value
    with pytest.raises(ConfigError, match=f"relation violated: {needle}"):
        validate(cfg)


def test_other_whole_step_divisions_pass(cfg):
    cfg["paper"]["control"]["frequency_hz"], cfg["sim"]["timestep"], cfg["sim"]["fee_every"] = 20.0, 0.005, 10
    validate(cfg)


def test_file_errors_name_the_file(tmp_path, cfg):
    bad = copy.deepcopy(cfg)
    bad["sim"]["timestep"] = -1
    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump(bad))
    with pytest.raises(ConfigError, match=str(p)):
        load_config(p)
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "absent.yaml")
    p.write_text("paper: [1, 2\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(p)
    p.write_text("# only a comment\n")      # a review: "'' must be a mapping of keys, got NoneType"
    with pytest.raises(ConfigError, match="is empty \\(or only comments\\)"):
        load_config(p)


def test_machine_mass_and_wheel_radius_follow_the_paper(cfg):
    m = cfg["machine"]
    assert m["chassis_mass"] + m["boom_mass"] + m["bucket_mass"] + 4 * m["wheel_mass"] == pytest.approx(121.0)
    # wheel radius from the 2.7 rad/s top wheel speed and the 0.37 m/s attack speed
    assert m["wheel_radius"] == pytest.approx(0.37 / 2.7, abs=0.001)


def test_capacity_and_normaliser_keys(cfg):
    """task.bucket_repose_deg (the gravel's angle of repose) and task.normalisers_from_pile (0/1),
    checked like every key; the former mass cap task.bucket_max_load is gone."""
    assert "bucket_max_load" not in cfg["task"]
    bad = copy.deepcopy(cfg)
    bad["task"]["bucket_repose_deg"] = 75.0
    with pytest.raises(ConfigError, match=r"'task\.bucket_repose_deg' = 75(\.0)? is out of range"):
        validate(bad)
    bad = copy.deepcopy(cfg)
    bad["task"]["normalisers_from_pile"] = 2
    with pytest.raises(ConfigError, match=r"'task\.normalisers_from_pile' = 2 is out of range"):
        validate(bad)
    bad = copy.deepcopy(cfg)
    bad["task"]["bucket_max_load"] = 37.5
    with pytest.raises(ConfigError, match="bucket_max_load"):
        validate(bad)


@pytest.mark.parametrize("alpha_max, phi_max, refused", [
    (30.0, 5.0, True),      # a review: a 30 deg pile of 5 deg soil was simulated as if it stood
    (55.0, 37.0, True),     # 50-55 deg piles of the shipped gravel: steeper than any of its repose angles
    (37.5, 37.0, True),
    (37.0, 37.0, False),    # a face at exactly the repose angle stands (just)
    (35.0, 37.0, False),    # the 10-35 deg files
])
def test_a_pile_steeper_than_its_repose_is_refused(cfg, alpha_max, phi_max, refused):
    """A cohesionless pile's face stands at most at its friction angle (the angle of repose):
    alpha_max_deg above pile.phi_max_deg, the largest friction angle a pile is drawn with, describes
    piles no material of the file can build."""
    cfg["paper"]["episode"]["alpha_max_deg"] = alpha_max
    cfg["paper"]["episode"]["alpha_min_deg"] = min(cfg["paper"]["episode"]["alpha_min_deg"], alpha_max - 1.0)
    cfg["pile"]["phi_max_deg"] = phi_max
    cfg["pile"]["phi_min_deg"] = min(cfg["pile"]["phi_min_deg"], phi_max)
    if refused:
        with pytest.raises(ConfigError, match=r"relation violated: paper.episode.alpha_max_deg <= pile.phi_max_deg"):
            validate(cfg)
    else:
        validate(cfg)


@pytest.mark.parametrize("eval_seed, episodes, refused", [
    (1_000_000, 120, False), (2_000_000, 10, True), (1_999_990, 20, True), (3_000_000, 1, True),
    (3_999_999, 5, True), (4_000_000, 100, False), (1_999_880, 120, False)])
def test_a_periodic_evaluation_on_the_held_out_seeds_is_refused(cfg, eval_seed, episodes, refused):
    """The periodic evaluation (which picks best/) must not see the piles of lhd eval / report --held-out /
    ship (2,000,000 on) or of ship's confirmation and lhd experiment paper (3,000,000 on) (a review, 2026-11-30)."""
    cfg["training"]["eval_seed"], cfg["training"]["eval_episodes"] = eval_seed, episodes
    if refused:
        with pytest.raises(ConfigError, match="outside the held-out evaluation seeds 2,000,000-3,999,999"):
            validate(cfg)
    else:
        validate(cfg)


def test_a_float_written_as_1e_4_is_read_as_a_number(cfg, tmp_path):
    """PyYAML reads `actor_lr: 1e-4` as the string '1e-4' (YAML 1.1): a float field takes it, an int field does not."""
    import yaml as _yaml

    text = _yaml.safe_dump(cfg).replace("actor_lr: 0.0001", "actor_lr: 1e-4")
    assert "actor_lr: 1e-4" in text
    p = tmp_path / "lr.yaml"
    p.write_text(text)
    assert load_config(str(p))["paper"]["ddpg"]["actor_lr"] == 1e-4
    cfg["training"]["eval_episodes"] = "10"
    cfg["paper"]["ddpg"]["critic_lr"] = "fast"
    with pytest.raises(ConfigError) as exc:
        validate(cfg)
    assert "'training.eval_episodes' = '10' is not a number" in str(exc.value)
    assert "'paper.ddpg.critic_lr' = 'fast' is not a number" in str(exc.value)
