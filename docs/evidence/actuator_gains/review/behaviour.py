"""Per-case behaviour means from json/<actor>_<case>_ep120.json: when and where the boom first lifts, with how much
in the bucket; how far the tip got; time; front / rear drift; tilt; stalled steps."""
import json, sys
import numpy as np
cases = sys.argv[1:] or ["nominal", "wheel_cap_80", "wheel_speed_m20", "hyd_speed_m25", "hyd_force_speed_m25",
                         "pile_cohesion_1500", "pile_phi_42_45", "vx_bias_m10", "floor_slippery_045"]
for a in ("rld", "rlc"):
    for c in cases:
        d = json.load(open(f"/tmp/robust/json/{a}_{c}_ep120.json"))
        e = d["episodes_detail"]
        m = lambda k: np.mean([x[k] for x in e if x.get(k) is not None])
        fails = [x for x in e if not x["success"]]
        print(f"{a} {c:20s} lift@step {m('first_lift_step'):5.1f} x {m('first_lift_x'):.3f} kg {m('first_lift_kg'):5.1f} | "
              f"x_reach-x_min {np.mean([x['x_max_reached']-x['x_min'] for x in e]):+.3f} | steps {m('steps'):5.1f} | "
              f"wheel {m('mean_wheel_cmd'):.2f} stall {m('stall_steps'):.1f} | drift f/r {m('front_drift_pct'):.1f}/{m('rear_drift_pct'):.1f} | "
              f"phiT {m('phi_final_deg'):.1f} | fails kg {sorted(round(x['loaded'],1) for x in fails)[:8]} slopes {sorted(set(x['slope'] for x in fails))}")
