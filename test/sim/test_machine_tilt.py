"""The machine's own pitch (rear frame), a metric of every episode: max_tilt_deg, the rear lifting
in a breakout (docs/modeling.md). Checked against orientations built by hand."""
import math

import mujoco
import numpy as np
import pytest

from lhd_loading_ros.task.metrics import aggregate
from lhd_sim_node.env import LhdLoadingEnv
from lhd_sim_node.simulator import LhdSimulator


@pytest.fixture(scope="module")
def cfg():
    from lhd_loading_ros.task.config import load_config
    return load_config()


def quat_mul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2)


@pytest.mark.parametrize("pitch_deg,yaw_deg", [(6.0, 0.0), (-4.0, 0.0), (9.6, 0.0), (5.0, 30.0), (-2.0, -170.0)])
def test_machine_pitch_is_the_nose_down_angle_of_the_rear_frame(cfg, pitch_deg, yaw_deg):
    """The free joint turned by hand: heading (about z) then pitch (about the machine's y; a
    positive turn about y sends the x axis, the nose, down). Any heading reads the same pitch."""
    sim = LhdSimulator(cfg)
    sim.reset(np.random.default_rng(0), alpha=math.radians(20.0))
    p, y = math.radians(pitch_deg), math.radians(yaw_deg)
    q = quat_mul((math.cos(y / 2), 0.0, 0.0, math.sin(y / 2)), (math.cos(p / 2), 0.0, math.sin(p / 2), 0.0))
    adr = sim.model.jnt_qposadr[sim.model.joint("base").id]
    sim.data.qpos[adr + 3:adr + 7] = q
    mujoco.mj_forward(sim.model, sim.data)
    # independently: the nose is the rotated x axis; its drop below the floor's plane
    nose = sim.data.xmat[sim.bid_rear].reshape(3, 3)[:, 0]
    assert nose[2] == pytest.approx(-math.sin(p), abs=1e-9)
    assert math.degrees(sim.machine_pitch()) == pytest.approx(pitch_deg, abs=1e-6)


def test_an_episode_reports_the_largest_tilt_it_went_through(cfg):
    """max_tilt_deg is the largest |machine pitch| at the control periods' ends, by the test's own
    bookkeeping of the same episode; the aggregate gives its mean and the share above 5 deg."""
    env = LhdLoadingEnv("rld", cfg)
    env.reset(seed=7, options={"slope_deg": 30.0, "material": "homogeneous"})
    seen = [abs(env.sim.machine_pitch())]
    rng = np.random.default_rng(3)
    done, info = False, {}
    while not done:        # drive in, then lift and curl at full speed: the hardest breakout
        a = np.array([1.0, -1.0, -1.0]) if env.steps < 12 else np.array([0.3, 1.0, 1.0])
        _, _, term, trunc, info = env.step(np.clip(a + rng.normal(0, 0.05, 3), -1, 1))
        seen.append(abs(env.sim.machine_pitch()))
        done = term or trunc
    res = info["episode_result"]
    assert math.isfinite(res.max_tilt_deg)
    assert res.max_tilt_deg == pytest.approx(math.degrees(max(seen)), abs=1e-9)
    agg = aggregate([res, res], 30.0)
    assert agg["max_tilt_deg"] == pytest.approx(res.max_tilt_deg)
    assert agg["tilt_over_5deg_rate"] == (1.0 if res.max_tilt_deg > 5.0 else 0.0)
