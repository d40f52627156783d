"""The sim node under drawn arm angle-sensor offsets (randomization.arm_offset_max_deg): its /lhd/joint_states
carry the arm's angles as the sensors read them, so that a controller computing the tip from the topics (the
policy node's task/kinematics.state_from_measurements, from /lhd/odom and /lhd/joint_states) gets the tip the
environment observes and ends the episode on. A real SimNode in this process over rclpy; what it publishes is
taken at its publishers."""
import copy

import numpy as np
import pytest
import yaml
from rclpy.parameter import Parameter

from rosutil import init_ros, shutdown_ros


def test_the_sim_node_publishes_the_arm_angles_its_sensors_read(tmp_path):
    from lhd_loading_ros.task.config import load_config
    from lhd_loading_ros.task.kinematics import ArmKinematics, state_from_measurements
    from lhd_sim_node.sim_node import SimNode

    cfg = copy.deepcopy(load_config())
    cfg["randomization"].update(enabled=1, arm_offset_max_deg=2.5)
    path = tmp_path / "lhd_params.yaml"
    path.write_text(yaml.safe_dump(cfg))
    init_ros()
    node = SimNode(parameter_overrides=[Parameter("config", value=str(path)), Parameter("mode", value="lockstep"),
                                        Parameter("auto_reset", value=False)])
    got = {"js": [], "odom": []}
    node.pub_js.publish = got["js"].append
    node.pub_odom.publish = got["odom"].append
    try:
        c = node.env.conditions
        assert abs(c.boom_offset_deg) > 0.1 and abs(c.bucket_offset_deg) > 0.1, c      # drawn for this episode
        kin = ArmKinematics.from_config(cfg)
        for _ in range(5):
            node._on_cmd(type("M", (), {"data": [2.0, -0.19, 0.2]})())
            js, od = got["js"][-1], got["odom"][-1]
            s, m = node.env.state, node.env.measured_state
            assert js.position[0] == pytest.approx(m.phi_boom) and js.position[1] == pytest.approx(m.phi_bucket)
            assert js.position[0] - s.phi_boom == pytest.approx(np.radians(c.boom_offset_deg))
            p, o = od.pose.pose.position, od.pose.pose.orientation
            joints = {n: (js.position[k], js.velocity[k]) for k, n in enumerate(js.name)}
            fromtopics = state_from_measurements(kin, (p.x, p.y, p.z), (o.w, o.x, o.y, o.z), od.twist.twist.linear.x,
                                                 joints, False, False)
            assert fromtopics.x_shovel == pytest.approx(m.x_shovel, abs=1e-6)
            assert fromtopics.z_shovel == pytest.approx(m.z_shovel, abs=1e-6)
            assert fromtopics.phi_shovel == pytest.approx(m.phi_shovel, abs=1e-9)
            assert abs(fromtopics.z_shovel - s.z_shovel) > 1e-3         # not the true tip
    finally:
        node.destroy_node()
        shutdown_ros()
