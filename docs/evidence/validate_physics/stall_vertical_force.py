# .venv/bin/python docs/evidence/validate_physics/stall_vertical_force.py > docs/evidence/validate_physics/stall_vertical_force.txt (2026-11-29)
"""Physics item 3 of docs/modeling.md's open findings, measured: at a push-only stall the FEE's vertical
force is faded by the tip speed (0-2 cm/s) while the tendon still transmits the push. What the tendon
transmits, what the FEE's full vertical component is, what is applied, and the front/rear normal loads."""
import math, numpy as np, mujoco
from lhd_loading_ros.task.config import load_config
from lhd_sim_node.simulator import LhdSimulator
from lhd_sim_node.fee_kernel import ST_FH, ST_FZ, OUT_FV, OUT_FH
cfg = load_config(None)
sim = LhdSimulator(cfg)
m, d = sim.model, sim.data
FRIC_T = mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON
wheels = sim._wheel_geoms
for deg in (15, 20, 25, 30):
    for seed in (0, 1):
        sim.reset(np.random.default_rng(seed), alpha=math.radians(deg), material="homogeneous")
        rows = []
        for k in range(60):
            sim.step(np.array([2.7, 0.0, 0.0]))
            if k < 40: continue
            idx = [i for i in range(d.nefc) if d.efc_type[i] == FRIC_T and d.efc_id[i] == sim.tid_fee]
            f_t = abs(float(d.efc_force[idx[0]])) if idx else 0.0
            fh = float(m.tendon_frictionloss[sim.tid_fee])
            fz_applied = float(d.xfrc_applied[sim.bid_bucket, 2])
            # normal loads per wheel
            N = {}
            for c in range(d.ncon):
                con = d.contact[c]
                for g in (con.geom1, con.geom2):
                    if g in wheels:
                        f6 = np.zeros(6); mujoco.mj_contactForce(m, d, c, f6)
                        N[g] = N.get(g, 0.0) + f6[0]
            nf = sum(N.get(g, 0.0) for g in wheels[:2]); nr = sum(N.get(g, 0.0) for g in wheels[2:])
            rows.append((f_t, fh, fz_applied, nf, nr, sim.state().v_x, sim._kout[OUT_FV], sim._kout[OUT_FH]))
        r = np.mean(np.array(rows), axis=0)
        st = sim.state()
        print(f"{deg} deg seed {seed}: tip x {st.x_shovel:.3f} v_x {r[5]:.4f}  tendon transmits {r[0]:.0f} N of FH {r[1]:.0f} N; "
              f"vertical applied {r[2]:.0f} N; front N {r[3]:.0f}  rear N {r[4]:.0f}  drift f/r {st.drift_front}/{st.drift_rear}; FEE FV/FH {r[6]/max(r[7],1e-9):.3f}, full FV x transmitted/FH {r[6]/max(r[7],1e-9)*r[0]:.0f} N")
