"""Write one modified copy of each actor's own lhd_params.yaml per robustness case (/tmp/robust/configs/).

Only config keys are changed here; cases that need a runtime change (command or observation
scaling, zones as the real end-zone node would publish them) are applied by robust_eval.py on top
of the copy named in CASES[...]["config"]. Usage: python make_configs.py
"""
import copy
import json
import sys
from pathlib import Path

import yaml

ROOT = Path("/work/main")
OUT = Path("/tmp/robust/configs")
ACTORS = {"rld": ROOT / "policies/rld_twin", "rlc": ROOT / "policies/rlc_twin_sil_bc"}


def recorded_normalisers(actor_dir):
    return json.loads((actor_dir / "policy.json").read_text())["observation"]["normalisers"]


# case -> list of (section path, key, new value); old value is read from the file
CONFIG_CASES = {
    "nominal": [],
    "hyd_force_m25": [("machine", "boom_force_limit", 525.0), ("machine", "bucket_force_limit", 225.0)],
    "wheel_torque_m20": [("machine", "wheel_torque_limit", 24.0)],
    "floor_slippery_045": [("machine", "wheel_friction", 0.45)],
    "floor_grippy_110": [("machine", "wheel_friction", 1.10)],
    "pile_cohesion_1500": [("pile", "cohesion_min", 1500.0), ("pile", "cohesion_max", 1500.0)],
    "pile_phi_42_45": [("pile", "phi_min_deg", 42.0), ("pile", "phi_max_deg", 45.0)],
    "machine_heavy_p15kg": [("machine", "chassis_mass", 102.0), ("machine", "total_mass", 136.0)],
    # a pile twice as wide as the bucket: changes the derived observation normalisers -> refused as is
    "pile_wide_080_refused": [("paper.episode", "w_pile", 0.8)],
    # workaround: the actor's recorded normalisers as the table values, derivation off; 14 voxel slices
    # keep the slice width of the trained pile (0.057 m); zones: robust_eval.py (as the end-zone node)
    "pile_wide_080": [("paper.episode", "w_pile", 0.8), ("paper.voxels", "n_y", 14),
                      ("task", "normalisers_from_pile", 0),
                      ("paper.observation", "d_end_max", "REC:d_end_max"),
                      ("paper.observation", "x_obs", "REC:x_obs")],
}


def get_sec(cfg, path):
    d = cfg
    for k in path.split("."):
        d = d[k]
    return d


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    changes = {}
    for name, actor_dir in ACTORS.items():
        base = yaml.safe_load((actor_dir / "lhd_params.yaml").read_text())
        rec = recorded_normalisers(actor_dir)
        for case, edits in CONFIG_CASES.items():
            cfg = copy.deepcopy(base)
            log = []
            for sec, key, val in edits:
                if isinstance(val, str) and val.startswith("REC:"):
                    val = rec[val[4:]]
                d = get_sec(cfg, sec)
                log.append(f"{sec}.{key}: {d.get(key)} -> {val}")
                d[key] = val
            path = OUT / f"{name}_{case}.yaml"
            path.write_text(f"# robustness case {case} for {actor_dir.name}: " + "; ".join(log or ["unchanged"]) + "\n"
                            + yaml.safe_dump(cfg, sort_keys=False))
            changes[f"{name}_{case}"] = log
    (OUT / "changes.json").write_text(json.dumps(changes, indent=1))
    print(json.dumps(changes, indent=1))


if __name__ == "__main__":
    sys.exit(main())
