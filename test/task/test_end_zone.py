"""The ROS-free core of the end-zone node (task/end_zone.py): which measurements are refused and
why, the wedge that cannot hold m_max, the republish rule, and the surveyed file in its three forms
and its mistakes."""
import math

import pytest

from lhd_loading_ros.task.end_zone import (InputLimits, Republisher, largest_change, load_survey, nominal_density,
                                           zones_of_pile)
from lhd_loading_ros.task.zones import Zones

r = math.radians
LIMITS = InputLimits(r(5.0), r(50.0), 5.0)


def test_nominal_density_is_the_config_midpoint(cfg):
    assert nominal_density(cfg) == pytest.approx((1760.0 + 2000.0) / 2)   # gravel (config pile.density_min/max)


@pytest.mark.parametrize("alpha, toe, res, text", [
    (math.nan, 0.0, 0.01, "slope (x) = nan not finite"),
    (r(20), math.inf, 0.01, "toe x (y) = inf not finite"),
    (r(20), 0.0, math.nan, "residual (z) = nan not finite"),
    (r(95), 0.0, 0.01, "slope 95.00 deg outside (0, 90) deg"),
    (0.0, 0.0, 0.01, "slope 0.00 deg outside (0, 90) deg"),
    (r(60), 0.0, 0.01, "slope 60.00 deg outside the physical range [5, 50] deg"),
    (r(3), 0.0, 0.01, "slope 3.00 deg outside the physical range [5, 50] deg"),
    (r(20), -5.2, 0.01, "toe x -5.200 m: expected |toe x| <= 5 m"),
])
def test_bad_measurements_name_the_value_and_what_is_expected(alpha, toe, res, text):
    why = LIMITS.problem(alpha, toe, res)
    assert why is not None and text in why, why


def test_good_measurements_pass():
    for a in (5.0, 20.0, 50.0):
        assert LIMITS.problem(r(a), 0.0, 0.01) is None
    assert LIMITS.problem(r(20), 4.99, 0.0) is None and LIMITS.problem(r(20), -4.99, 0.0) is None


def test_a_wedge_lighter_than_m_max_has_no_end_zone(params):
    # 50 deg, 500 kg/m^3: 500 * 0.4 * 0.68^2 / (2 tan 50 deg) = 38.8 kg < m_max = 170 kg
    with pytest.raises(ValueError, match="holds 39 kg, less than m_max = 170 kg"):
        zones_of_pile(r(50.0), 0.0, 500.0, params)
    # 3,250 kg/m^3 at the steepest accepted slope holds 252 kg: fine
    z = zones_of_pile(r(50.0), 0.0, 3250.0, params)
    assert z == Zones.for_measured_pile(r(50.0), 0.0, 3250.0, params)


def test_republish_only_beyond_the_threshold(params):
    rep = Republisher(0.02)
    z0 = zones_of_pile(r(20.0), 0.0, 3250.0, params)
    assert rep.offer(z0) and rep.published == z0                 # the first one always
    assert not rep.offer(z0)                                     # the same again: no
    z1 = zones_of_pile(r(20.0), 0.015, 3250.0, params)           # toe 15 mm: every x limit 15 mm
    assert largest_change(z1, z0) == pytest.approx(0.015)
    assert not rep.offer(z1) and rep.published == z0
    z2 = zones_of_pile(r(20.0), 0.035, 3250.0, params)           # 20 mm from z1, 35 mm from z0 (published)
    assert rep.offer(z2) and rep.published == z2
    # the slope: 0.1 deg moves x_cutoff by 0.68 / sin^2(20 deg) * 0.1 deg = 0.0101 m, x_max by
    # x_max / sin(40 deg) * 0.1 deg = 0.0023 m: below; 0.3 deg: x_cutoff 0.030 m, above
    assert not rep.offer(zones_of_pile(r(20.1), 0.035, 3250.0, params))
    assert largest_change(zones_of_pile(r(20.3), 0.035, 3250.0, params), z2) == pytest.approx(
        0.68 / math.tan(r(20.0)) - 0.68 / math.tan(r(20.3)))
    assert rep.offer(zones_of_pile(r(20.3), 0.035, 3250.0, params))
    # an operator's change (force) goes out however small
    z3 = zones_of_pile(r(20.3), 0.035, 3240.0, params)
    assert not rep.offer(z3) and rep.offer(z3, force=True) and rep.published == z3
    assert not rep.offer(z3, force=True)                         # but not the same zones twice


def survey(tmp_path, text, params, name="s.yaml"):
    f = tmp_path / name
    f.write_text(text)
    return load_survey(str(f), params, LIMITS)


def test_survey_of_a_pile_gives_the_measured_zones(tmp_path, params):
    s = survey(tmp_path, "slope_deg: 22\ntoe_x: 0.05\n", params)
    assert s.is_pile and s.density is None
    assert s.zones_for(3250.0, params) == Zones.for_measured_pile(r(22.0), 0.05, 3250.0, params)
    s = survey(tmp_path, "slope_deg: 22.0\ntoe_x: 0\ndensity: 2900\n", params)
    assert s.density == 2900.0


def test_survey_of_the_end_zone_alone(tmp_path, paper_params):
    params = paper_params
    z = survey(tmp_path, "end_zone: [0.5, 0.8, 0.35]\n", params).zones_for(1.0, params)
    # the paper's observation zone about the toe, and no cut before its end
    assert z.as_list() == pytest.approx([0.5, 0.8, 0.35, 1.0, -0.1, 1.0, 0.2, 0.4])
    z = survey(tmp_path, "end_zone: [0.5, 0.8, 0.35]\nx_cutoff: 0.9\n", params).zones_for(1.0, params)
    assert z.x_cutoff == 0.9


def test_survey_of_all_eight_limits(tmp_path, params):
    want = [0.5, 0.8, 0.35, 1.5, -0.1, 1.0, 0.2, 0.4]
    as_map = ("zones: {x_min: 0.5, x_max: 0.8, z_min: 0.35, x_cutoff: 1.5, x_obs_start: -0.1, x_obs_end: 1.0, "
              "y_half: 0.2, z_top: 0.4}\n")
    assert survey(tmp_path, as_map, params).zones.as_list() == want
    assert survey(tmp_path, f"zones: {want}\nend_zone: {want[:3]}\n", params).zones.as_list() == want


@pytest.mark.parametrize("text, msg", [
    ("slope_deg: 22\ntoe_x: 0\ndensty: 3000\n", "unknown key 'densty' (did you mean 'density'?)"),
    ("slope_deg: 22\n", "a surveyed pile with slope_deg and toe_x"),
    ("slope_deg: 60\ntoe_x: 0\n", "slope 60.00 deg outside the physical range [5, 50] deg"),
    ("slope_deg: twenty\ntoe_x: 0\n", "'slope_deg' = 'twenty': expected a finite number"),
    ("slope_deg: .nan\ntoe_x: 0\n", "'slope_deg' = nan: expected a finite number"),
    ("slope_deg: 22\ntoe_x: 7\n", "toe x 7.000 m: expected |toe x| <= 5 m"),
    ("slope_deg: 22\ntoe_x: 0\ndensity: 3.2\n", "bulk density 3.2 kg/m^3 outside [500, 6000] kg/m^3"),
    ("end_zone: [0.8, 0.5, 0.35]\n", "x_min 0.8 must be below x_max 0.5"),
    ("end_zone: [0.5, 0.8]\n", "'end_zone' = [0.5, 0.8]: expected 3 numbers [x_min, x_max, z_min]"),
    ("end_zone: [0.5, 0.8, 0.35]\nslope_deg: 20\n", "not both"),
    # a review: zone sets no pile can have were published latched
    ("end_zone: [0.5, 0.8, 0.35]\nx_cutoff: 0.2\n", "the end zone starts at x_min 0.5 m, at or beyond the restricted zone"),
    ("end_zone: [5.5, 9.8, 0.35]\n", "x_min 5.5 m, at or beyond the restricted zone (x_cutoff 1.3725"),
    ("end_zone: [0.5, 0.8, -5.0]\n", "z_min -5 m must lie on or above the pile's floor"),
    ("zones: {x_min: 0.5, x_max: 0.8, z_min: 0.5, x_cutoff: 1.58, x_obs_start: -0.1, x_obs_end: 1.0, y_half: 0.2, "
     "z_top: 0.4}\n", "below the observation zone's top z_top 0.4 m"),
    ("zones: {x_min: 0.5, x_max: 0.8, z_min: 0.35, x_cutoff: 1.58, x_obs_start: -0.1, x_obs_end: 0.3, y_half: 0.2, "
     "z_top: 0.4}\n", "outside the observation zone [-0.1, 0.3] m"),
    ("zones: {x_min: 0.5, x_max: 0.8}\n", "missing z_min, x_cutoff"),
    ("zones: [0.5, 0.8, 0.35, 1.5, -0.1, 1.0, 0.2, 0.4]\nend_zone: [0.5, 0.9, 0.35]\n", "disagrees"),
    ("- 0.5\n- 0.8\n", "expected a mapping"),
    ("end_zone: [0.5, 0.8\n", "not valid YAML"),
])
def test_survey_mistakes_give_one_line_naming_file_key_and_expectation(tmp_path, params, text, msg):
    with pytest.raises(ValueError) as exc:
        survey(tmp_path, text, params)
    m = str(exc.value)
    assert msg in m and m.startswith(f"surveyed_file {tmp_path / 's.yaml'}: ") and "\n" not in m, m


def test_survey_file_missing(tmp_path, params):
    with pytest.raises(ValueError, match=r"surveyed_file .*nope.yaml: cannot read it \(No such file"):
        load_survey(str(tmp_path / "nope.yaml"), params, LIMITS)


def test_the_shipped_example_is_a_valid_survey(params):
    from pathlib import Path

    example = Path(__file__).resolve().parents[2] / "config" / "end_zone_surveyed.example.yaml"
    s = load_survey(str(example), params, LIMITS)
    assert s.is_pile and s.alpha == pytest.approx(r(22.0)) and s.toe_x == 0.0


def test_every_zone_set_the_end_zone_node_builds_is_accepted(params):
    """The receivers (supervisor, twin) parse /lhd/pile/zones with from_list: its checks must pass
    every zone set the end-zone node builds from a LiDAR estimate it accepts (5-50 deg) and a
    plausible density, including the steep piles whose end zone reaches past the cut (x_max >
    x_cutoff: the pile's 170 kg lie behind L - d_cutoff, by hand at 45 deg and 1,760 kg/m^3:
    s = sqrt(2 x 170 / (1760 x 0.4 x 1)) = 0.695 m > L = 0.68 m, capped at 0.68, cut at 0.58)."""
    z45 = Zones.for_measured_pile(math.radians(45.0), 0.0, 1760.0, params)
    assert z45.x_max == pytest.approx(0.68) and z45.x_cutoff == pytest.approx(0.58)
    for deg in range(5, 51):
        for rho in (1400.0, 1500.0, 1760.0, 2000.0, 2200.0, 2700.0):
            z = Zones.for_measured_pile(math.radians(deg), 0.0, rho, params)
            assert Zones.from_list(z.as_list()) == z, (deg, rho)
