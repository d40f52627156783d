"""Zones, the 12-dim observation and the action mapping/filters, with hand-computed values."""
import math

import numpy as np
import pytest

from lhd_loading_ros.task.actions import (apply_variant_filter, hybrid_filter, rlc_deploy_filter, rld_filter, to_actuator,
                                     validate_action)
from lhd_loading_ros.task.observation import OBS_HIGH, OBS_LOW, build_observation
from lhd_loading_ros.task.state import LhdState
from lhd_loading_ros.task.zones import Zones, classify, in_end_zone, in_restricted_zone


from test_pile import uniform_pile

r = math.radians


def zones():
    return Zones(x_min=0.7, x_max=1.1, z_min=0.35, x_cutoff=1.6, x_obs_start=-0.1, x_obs_end=1.0, y_half=0.2,
                 z_top=0.4)


def test_end_zone_from_masses(params):
    p = uniform_pile(20.0, rho=1800.0)
    z = Zones.for_pile(p, params)
    # x where the wedge holds m: sqrt(2 m / (rho w tan alpha))
    assert z.x_min == pytest.approx(math.sqrt(2 * 65 / (1800 * 0.4 * math.tan(r(20)))), rel=0.01)
    assert z.x_max == pytest.approx(math.sqrt(2 * 170 / (1800 * 0.4 * math.tan(r(20)))), rel=0.01)
    assert z.x_cutoff == pytest.approx(p.L - 0.1)
    # the observation zone: x_obs derived from the gravel pile family (test_gravel_geometry.py)
    assert (z.x_obs_start, z.x_obs_end, z.y_half) == pytest.approx((-0.1, -0.1 + params.x_obs, 0.2))
    # steeper piles: the end zone comes closer
    z30 = Zones.for_pile(uniform_pile(30.0, rho=1800.0), params)
    assert z30.x_min < z.x_min and z30.x_max < z.x_max


def test_zone_membership():
    z = zones()
    assert in_end_zone(0.8, 0.36, z) and classify(0.8, 0.0, 0.36, z) == "end"
    assert not in_end_zone(0.7, 0.5, z)          # open interval at x_min
    assert not in_end_zone(0.8, 0.35, z)         # z must exceed z_min
    assert classify(0.5, 0.0, 0.1, z) == "permitted"
    assert classify(0.5, 0.0, 0.6, z) == "permitted"  # no height limit
    assert classify(1.05, 0.0, 0.1, z) == "restricted"  # past the observation zone, below z_min
    assert classify(-0.2, 0.0, 0.0, z) == "restricted"
    assert classify(0.5, 0.25, 0.0, z) == "restricted"
    cut = Zones(0.7, 1.1, 0.35, 0.8, -0.1, 1.0, 0.2, 0.4)
    assert in_restricted_zone(0.85, 0.0, 0.1, cut)  # past x_cutoff = L - d_cutoff


def test_observation_hand_computed(paper_params):
    params = paper_params
    s = LhdState(x_shovel=0.45, y_shovel=0.1, z_shovel=0.1, phi_shovel=r(15), v_x=0.25, drift=True,
                 phi_boom=-0.475, dphi_boom=-0.0955, phi_bucket=0.65, dphi_bucket=0.1)
    o = build_observation(s, r(22.5), 0.885, params)
    # x: 2(0.45+0.1)/1.1-1 = 0; y: 0.1/0.2 = 0.5; z: 2*0.1/0.4-1 = -0.5; pitch: 2(15+60)/150-1 = 0;
    # v_x: 0.25/0.5; drift 1; boom: 2(-0.475+1)/1.05-1 = 0; rate -0.0955/0.191; bucket: 2(0.65+0.1)/1.5-1 = 0;
    # rate 0.1/0.2; d_end |0.45-0.885|/0.87 = 0.5; alpha (22.5-15)/15 = 0.5
    np.testing.assert_allclose(o, [0, 0.5, -0.5, 0, 0.5, 1, 0, -0.5, 0, 0.5, 0.5, 0.5], atol=1e-6)
    assert o.dtype == np.float32 and o.shape == (12,)


def test_observation_is_clipped_and_rejects_nan(params):
    s = LhdState(5.0, 1.0, -1.0, r(170), 9.0, False, -3.0, -5.0, 3.0, 5.0)
    o = build_observation(s, r(40), -3.0, params)
    assert np.all(o >= OBS_LOW) and np.all(o <= OBS_HIGH)
    s.v_x = float("nan")
    with pytest.raises(ValueError, match="non-finite components: v_x"):
        build_observation(s, r(20), 1.0, params)


def test_action_mapping_ends_and_middle(params):
    u = to_actuator(np.array([1.0, 1.0, -1.0]), params)
    assert u.tolist() == [2.7, 0.0, 0.0]
    u = to_actuator(np.array([-1.0, -1.0, 1.0]), params)
    assert u.tolist() == [0.0, -0.191, 0.2]
    np.testing.assert_allclose(to_actuator(np.zeros(3), params), [1.35, -0.0955, 0.1])


def test_rld_and_rlc_filters(params):
    assert hybrid_filter(0.0, 0.0) == -1.0 and hybrid_filter(1e-9, 0.0) == 1.0
    np.testing.assert_array_equal(rld_filter(np.array([0.3, 0.2, -0.4]), params), [0.3, 1.0, -1.0])
    np.testing.assert_array_equal(rlc_deploy_filter(np.array([0.3, 0.61, -0.91]), params), [0.3, 1.0, -1.0])
    np.testing.assert_array_equal(rlc_deploy_filter(np.array([0.3, 0.6, -0.9]), params), [0.3, 0.6, -0.9])
    np.testing.assert_array_equal(apply_variant_filter(np.array([0.1, 0.7, -0.95]), "rlc", params), [0.1, 0.7, -0.95])
    np.testing.assert_array_equal(apply_variant_filter(np.array([0.1, 0.7, -0.95]), "rlc", params, deploy=True),
                                  [0.1, 1.0, -1.0])
    with pytest.raises(ValueError, match="unknown variant"):
        apply_variant_filter(np.zeros(3), "ppo", params)


def test_invalid_actions_are_rejected():
    with pytest.raises(ValueError, match=r"non-finite components \['boom'\]"):
        validate_action([0.0, float("nan"), 0.0])
    with pytest.raises(ValueError, match=r"out of range: wheels=1\.5.*expected each component in \[-1, 1\]"):
        validate_action([1.5, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        validate_action([0.0, 0.0])
    assert validate_action([1.0 + 1e-9, -1.0, 0.0])[0] == 1.0
