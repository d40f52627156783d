"""Export the actor of a kept training checkpoint (lhd train --keep-checkpoint) to a policy directory, so that
`lhd experiment paper` and `lhd eval` can run it beside the run's final actor. Run from the repository root:
    .venv/bin/python docs/evidence/margin8/export_checkpoint.py runs/X/seed_0/checkpoint_step300000.pt CONFIG OUT_DIR
The checkpoint's config hash must be the config's (the same check `lhd train --branch-from` makes)."""
import sys
from pathlib import Path

import torch

from lhd_loading_ros.learning.ddpg import DdpgConfig
from lhd_loading_ros.learning.export import export_actor
from lhd_loading_ros.learning.mlp import FlatMlp
from lhd_loading_ros.learning.train import load_checkpoint
from lhd_loading_ros.task.actions import ACT_DIM
from lhd_loading_ros.task.config import config_hash, load_config
from lhd_loading_ros.task.observation import OBS_DIM

if len(sys.argv) != 4:
    sys.exit("usage: export_checkpoint.py CHECKPOINT.pt PARAMETER_FILE.yaml OUT_DIR (the checkpoint of `lhd train "
             "--keep-checkpoint`, the parameter file it was trained with, the policy directory to write)")
ckpt_path, cfg_path, out = sys.argv[1:4]
cfg = load_config(cfg_path)
try:
    ck = load_checkpoint(Path(ckpt_path))     # the trainer's own reader (weights only, a clear error)
except ValueError as exc:
    sys.exit(str(exc))
if ck["config_hash"] != config_hash(cfg):
    sys.exit(f"{ckpt_path}: config hash {ck['config_hash']} is not {cfg_path}'s {config_hash(cfg)}")
flat = ck["agent"]["actor"]
sizes = [OBS_DIM, *DdpgConfig.from_config(cfg).hidden_sizes, ACT_DIM]     # as learning.ddpg.DdpgAgent builds it
actor = FlatMlp(sizes, "tanh")
if flat.shape != actor.flat.shape:
    sys.exit(f"{ckpt_path}: the actor has {flat.numel()} parameters, {sizes} needs {actor.flat.numel()}")
with torch.no_grad():
    actor.flat.copy_(flat)
export_actor(out, actor, cfg, {"variant": ck["variant"], "seed": ck["seed"], "config_hash": ck["config_hash"],
                               "steps": int(ck["step"]), "evaluation": {}, "from_checkpoint": ckpt_path})
print(f"{out}: actor of {ckpt_path} (step {int(ck['step'])})")
