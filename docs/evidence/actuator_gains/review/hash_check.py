"""Which physically legitimate parameter changes the project's checks accept: for each single-key change of
policies/rld_twin/lhd_params.yaml, task.config.hash_matches / LoadedPolicy.config_matches (the policy node:
a warning when False) and LoadedPolicy.observation_mismatch (lhd eval, the policy node, up real: refusal)."""
import copy, yaml
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task.config import validate, hash_matches
pol = load_policy("/work/main/policies/rld_twin")
base = yaml.safe_load(open("/work/main/policies/rld_twin/lhd_params.yaml"))
tests = [("machine", "boom_force_limit", 525.0), ("machine", "wheel_friction", 0.45), ("pile", "cohesion_max", 1500.0),
         ("pile", "density_min", 1500.0), ("pile", "density_max", 2200.0), ("paper.episode", "w_pile", 0.8),
         ("paper.episode", "h_pile", 0.5), ("paper.episode", "h_pile", 0.85), ("paper.episode", "d_attack_max", 0.6),
         ("paper.end_zone", "m_max", 150.0), ("paper.control", "wheels_max", 2.16), ("paper.control", "boom_min", -0.143),
         ("randomization", "enabled", 1), ("randomization", "tyre_friction_min", 0.4)]
for sec, key, val in tests:
    c = copy.deepcopy(base)
    d = c
    for k in sec.split("."):
        d = d[k]
    old = d[key]; d[key] = val
    try:
        cfg = validate(c)
    except Exception as exc:
        print(f"{sec}.{key} {old} -> {val}: config invalid: {exc}"); continue
    mm = pol.observation_mismatch(cfg)
    print(f"{sec}.{key} {old} -> {val}: hash_matches {hash_matches(pol.meta['config_hash'], cfg)}, "
          f"config_matches {pol.config_matches(cfg)}, refused {mm is not None}" + (f" ({mm.split(':')[1][:90].strip()})" if mm else ""))
