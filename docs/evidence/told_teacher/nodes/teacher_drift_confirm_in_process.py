"""The teacher controller (policy/teacher.TeacherCore) in process, fed the simulator's measurements as
the sim node publishes them (true drift flags), with teacher_drift_confirm 1 / 4 / 6: 10 attempts a
slope (seeds 100-109, the materials alternating), the paper's 10 s limit. Run from the repository root:
  .venv/bin/python docs/evidence/told_teacher/nodes/teacher_drift_confirm_in_process.py"""
import math, sys
import numpy as np
sys.path.insert(0, "test/policy")
from test_policy_core import measurements
from lhd_sim_node.env import LhdLoadingEnv
from lhd_loading_ros.policy.core import Inputs
from lhd_loading_ros.policy.teacher import TeacherCore, TeacherSetting
from lhd_loading_ros.task.kinematics import ArmKinematics
env = LhdLoadingEnv("rld")
cfg = env.cfg
for n in (1, 4, 6):
    core = TeacherCore(TeacherSetting.from_config(cfg), env.p, ArmKinematics.from_config(cfg), n)
    for slope in (15, 20, 25, 30):
        res = []
        for seed in range(10):
            env.reset(seed=100 + seed, options={"slope_deg": slope, "material": "homogeneous" if seed % 2 else "nonhomogeneous"})
            core.reset(); inp = Inputs(); z = env.zones; now = 0.0
            while True:
                now += env.p.control_dt
                pos, quat, v, joints, f, r = measurements(env)
                for name, value in (("joints", joints), ("odom", (pos, quat, v)), ("drift_front", f), ("drift_rear", r),
                                    ("slope", math.radians(slope)), ("end_zone", (z.x_min, z.x_max, z.z_min))):
                    inp.put(name, value, now)
                d = core.decide(inp, now, 0.5)
                _, _, term, trunc, info = env.step_actuator(np.asarray(d.command))
                if term or trunc or env.steps >= 100:
                    rr = info["episode_result"] if (term or trunc) else env.result("timeout", truncated=True)
                    break
            res.append(rr)
        ok = [x for x in res if x.success]
        print(n, slope, f"success {len(ok)/len(res):.2f} mass {np.mean([x.loaded for x in ok]) if ok else float('nan'):.1f} time {np.mean([x.elapsed_s for x in ok]) if ok else float('nan'):.2f} front {np.mean([x.front_drift_pct for x in ok]) if ok else float('nan'):.1f}")
