"""task.midgoal_from_pile: r_midgoal and r_inact switch at the episode pile's end-zone x_min instead of
the paper's constant x_midgoal. By hand: the wedge's x_min from its mass, the two terms on either side of
it; off, the reward is the paper's and the config hash unchanged; on, the environment's tracker uses the
pile it generated, and the card records the setting."""
import copy
import math

import numpy as np
import pytest

from lhd_loading_ros.task import reward as R
from lhd_loading_ros.task.config import config_hash
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.zones import Zones


def with_midgoal(cfg, on=1):
    c = copy.deepcopy(cfg)
    c["task"]["midgoal_from_pile"] = on
    return c


def wedge_zones(alpha_deg, density, p):
    """A measured wedge's zones; x_min by hand: m = density * w * tan(alpha) * s^2 / 2."""
    z = Zones.for_measured_pile(math.radians(alpha_deg), 0.0, density, p)
    s = math.sqrt(2.0 * p.m_min / (density * p.w_pile * math.tan(math.radians(alpha_deg))))
    assert z.x_min == pytest.approx(s, rel=1e-12)
    return z


def test_off_is_the_papers_constant(cfg):
    assert cfg["task"]["midgoal_from_pile"] == 0
    p = TaskParams.from_config(cfg)
    z = wedge_zones(15.0, 1760.0, p)
    assert p.for_pile(z) is p and p.x_midgoal == 0.54 and p.d_midgoal_max == 0.44
    stripped = copy.deepcopy(cfg)
    del stripped["task"]["midgoal_from_pile"]
    # reward shaping: in no case part of the hash (what the actor sees and commands is the same)
    assert config_hash(cfg) == config_hash(stripped) == config_hash(with_midgoal(cfg))


@pytest.mark.parametrize("alpha_deg, density, x_min", [
    # sqrt(2 * 65 / (density * 0.4 * tan(alpha))), worked out on paper
    (15.0, 1760.0, 0.83015), (30.0, 1760.0, 0.56554), (30.0, 2000.0, 0.53053)])
def test_on_the_midgoal_is_the_piles_x_min(cfg, alpha_deg, density, x_min):
    p = TaskParams.from_config(with_midgoal(cfg))
    q = p.for_pile(wedge_zones(alpha_deg, density, p))
    assert q.x_midgoal == pytest.approx(x_min, abs=2e-5)
    assert q.d_midgoal_max == pytest.approx(x_min - 0.1, abs=1e-4)   # largest d_midgoal: from d_init
    # the paper's 0.54 m is a 30 deg pile's: within 0.03 m over the gravel densities
    if alpha_deg == 30.0:
        assert abs(q.x_midgoal - 0.54) < 0.03
    # everything else is the paper's
    assert q.R_midgoal == p.R_midgoal and q.R_inact == p.R_inact and q.phi_target == p.phi_target


def test_terms_on_a_15_deg_pile(cfg):
    """At x = 0.7 m on a 15 deg pile: the paper's constant has r_inact charging -50 for an arm held
    still and no r_midgoal; the pile's x_min (0.830 m) still asks for depth, -25 (0.830 - 0.7) / 0.730."""
    paper = TaskParams.from_config(cfg)
    q = TaskParams.from_config(with_midgoal(cfg)).for_pile(wedge_zones(15.0, 1760.0, paper))
    assert R.r_inact(0.0, 0.0, 0.7, paper) == -50.0 and R.r_midgoal(0.7, paper) == 0.0
    assert R.r_inact(0.0, 0.0, 0.7, q) == 0.0
    assert R.r_midgoal(0.7, q) == pytest.approx(-25.0 * (0.83015 - 0.7) / (0.83015 - 0.1), abs=5e-4)
    # past it, lifting and curling at half the top rates or more is free, less is charged
    assert R.r_inact(-0.6 * 0.191, 0.6 * 0.2, 0.9, q) == 0.0
    assert R.r_inact(-0.4 * 0.191, 0.6 * 0.2, 0.9, q) == -50.0


def test_in_the_environment(cfg):
    """A seeded 15 deg episode driving in with the arm still: with the setting the tracker's x_midgoal
    is the generated pile's x_min, and each step's r_midgoal / r_inact are the hand formulas at the
    tip's x; off, the paper's 0.54 m."""
    from lhd_sim_node.env import LhdLoadingEnv

    for on in (0, 1):
        env = LhdLoadingEnv(config=with_midgoal(cfg, on), variant="rld")
        env.reset(seed=5, options={"slope_deg": 15.0})
        xm = env.sim.zones.x_min if on else 0.54
        assert env.tracker.p.x_midgoal == (env.sim.zones.x_min if on else 0.54)
        if on:
            assert 0.75 < xm < 0.95      # a 15 deg gravel pile: far deeper than 0.54 m
        seen_past = seen_before = False
        for _ in range(40):
            _, _, term, trunc, info = env.step(np.array([1.0, 1.0, -1.0]))   # drive, boom and bucket still
            x = env.state.x_shovel
            if x < xm:
                seen_before = True
                assert info["terms"]["midgoal"] == pytest.approx(-25.0 * (xm - x) / (xm - 0.1), rel=1e-9)
                assert info["terms"]["inact"] == 0.0
            else:
                seen_past = True
                assert info["terms"]["midgoal"] == 0.0 and info["terms"]["inact"] == -50.0
            if term or trunc:
                break
        assert seen_before and (seen_past or on)


def test_card_records_it(cfg, tmp_path):
    from lhd_loading_ros.learning.export import export_actor
    from lhd_loading_ros.learning.mlp import FlatMlp
    from lhd_loading_ros.policy.actor_file import load_policy

    actor = FlatMlp([12, 8, 3], out_act="tanh")
    for on in (0, 1):
        export_actor(tmp_path / f"p{on}", actor, with_midgoal(cfg, on), {"variant": "rld", "seed": 0, "steps": 0})
        tw = load_policy(tmp_path / f"p{on}").meta["trained_with"]
        assert tw.get("midgoal_from_pile", 0) == on
