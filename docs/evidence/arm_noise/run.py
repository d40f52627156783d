"""The arm's angle sensors read with noise, and the rates the Due differentiates from them: every shipped machine
actor, with the firmware's rate over its 0.1 s window (the environment as shipped: `lhd eval --stress arm_noise`
at 0.1 deg) and over one 10 ms sensor frame (the firmware before 2026-11-29, replayed here: the reading 10 ms back
is the true angle then, taken as the angle now less the joint's speed times 10 ms, with its own noise and counts).

    .venv/bin/python docs/evidence/arm_noise/run.py > docs/evidence/arm_noise/table.md

120 episodes each on the held-out seed 2,000,000 (the stratified 15-30 deg set), the RLC with the deployment
filter, the zones the pile's (as `lhd eval`)."""
from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

from lhd_loading_ros.learning.evaluate import evaluate
from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.task import randomization
from lhd_loading_ros.task.arm_sensors import quantize
from lhd_loading_ros.task.config import load_config
from lhd_sim_node.env import LhdLoadingEnv

ROOT = Path(__file__).resolve().parents[3]
ACTORS = ("rld_machine", "rlc_gains", "rld_gains", "rld_told_teacher", "rld", "rlc")
FRAME = 0.01          # s: one sensor frame at the config's 100 Hz


class OneFrameEnv(LhdLoadingEnv):
    """The rates over one sensor frame, as the firmware differentiated before its window."""

    def _measured(self, s):
        m = super()._measured(s)
        c = self.conditions
        if self._arm_rates is None:
            return m
        sd = math.radians(c.arm_angle_noise_deg)
        rates = {}
        for name in ("boom", "bucket"):
            back = getattr(s, "phi_" + name) - getattr(s, "dphi_" + name) * FRAME
            back = quantize(back + (float(self.np_random.normal(0.0, sd)) if sd > 0.0 else 0.0), c.arm_encoder_counts)
            rates["dphi_" + name] = (getattr(m, "phi_" + name) - back) / FRAME
        return replace(m, **rates)


def run(actor: str, env_cls, noise_deg: float) -> dict:
    d = ROOT / "policies" / actor
    cfg = load_config(d / "lhd_params.yaml" if (d / "lhd_params.yaml").exists() else None)
    pol = load_policy(d)
    env = env_cls(pol.variant, cfg, deploy_filter=pol.variant == "rlc", zones_from_estimate=True)
    randomization.ARM_NOISE_DEG = noise_deg       # the stress case's noise (its counts stay 4,096)
    return evaluate(env, pol.actor, 120, 2_000_000, cfg["task"]["bucket_capacity"], breakdown=False, stress="arm_noise")


def main() -> int:
    print("| actor | nominal | 0.1 deg, window 0.1 s | 0.1 deg, one 10 ms frame | 0.3 deg, window 0.1 s | "
          "0.3 deg, one 10 ms frame | no noise, one 10 ms frame |")
    print("|---|---|---|---|---|---|---|")
    for actor in ACTORS:
        cells = []
        d = ROOT / "policies" / actor
        cfg = load_config(d / "lhd_params.yaml" if (d / "lhd_params.yaml").exists() else None)
        pol = load_policy(d)
        env = LhdLoadingEnv(pol.variant, cfg, deploy_filter=pol.variant == "rlc", zones_from_estimate=True)
        nom = evaluate(env, pol.actor, 120, 2_000_000, cfg["task"]["bucket_capacity"], breakdown=False)
        cells.append(f"{nom['success_rate']:.3f} / {nom['aml']:.1f} kg")
        for noise in (0.1, 0.3):
            for cls in (LhdLoadingEnv, OneFrameEnv):
                r = run(actor, cls, noise)
                cells.append(f"{r['success_rate']:.3f} / {r['aml']:.1f} kg")
        r = run(actor, OneFrameEnv, 0.0)          # the encoder's counts alone
        cells.append(f"{r['success_rate']:.3f} / {r['aml']:.1f} kg")
        print(f"| `{actor}` | " + " | ".join(cells) + " |", flush=True)
    print("\nsuccess / AML (mean loaded mass), 120 episodes each; every case but nominal with 4,096 counts per turn")
    return 0


if __name__ == "__main__":
    sys.exit(main())
