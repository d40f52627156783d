"""Exported actors: a policy directory the policy node loads without training code or torch.

Layout of a policy directory (format ``lhd-actor/1``, docs/training.md says why):

- ``actor.npz``: the layer weights ``W0, b0, W1, b1, ...`` as float32 arrays (``np.load`` with
  ``allow_pickle=False``: no Python object is ever unpickled);
- ``policy.json``: architecture (layer sizes, ReLU hidden, tanh output), variant, observation
  names and normalization, action names and actuator ranges, filter thresholds, the config
  hash, seed, steps, evaluation figures, the SHA-256 of ``actor.npz`` and ``trained_ranges``
  (``{"slope_deg": [lo, hi]}``: the slopes the actor was trained on; the policy node refuses
  others), and ``card_sha256``: the SHA-256 of the fields that decide how the actor is run
  (:data:`SEALED_FIELDS`: its variant, scaling, actuator mapping, filters, trained ranges, config hash
  and what it was trained with), so that a card edited by hand after export (its variant changed from
  rld to rlc, a slope range widened) is refused instead of running the actor otherwise than it was
  trained. Cards exported before the seal (2026-12-01) carry none and load as before.

:class:`NumpyActor` runs the network in numpy (about 10 us per observation).
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lhd_loading_ros.task.config import hash_matches, sim_change_note

FORMAT = "lhd-actor/1"
ACTOR_FILE = "actor.npz"
META_FILE = "policy.json"
OBS_SIZE, ACT_SIZE = 12, 3       # an actor's input (task.observation.OBS_NAMES) and output (task.actions.ACT_NAMES)


class PolicyFileError(ValueError):
    """A policy directory is missing, incomplete or inconsistent."""


class NumpyActor:
    """mu(o) = tanh(W_n relu(... relu(W_1 o + b_1) ...) + b_n), float32."""

    def __init__(self, layers: list[tuple[np.ndarray, np.ndarray]]):
        if not layers:
            raise PolicyFileError("actor has no layers")
        self.layers = [(np.ascontiguousarray(W, dtype=np.float32), np.ascontiguousarray(b, dtype=np.float32))
                       for W, b in layers]
        for j, (W, b) in enumerate(self.layers):
            if W.ndim != 2 or b.shape != (W.shape[0],):
                raise PolicyFileError(f"layer {j}: weight {W.shape} and bias {b.shape} do not form a dense layer")
            if j and W.shape[1] != self.layers[j - 1][0].shape[0]:
                raise PolicyFileError(f"layer {j} takes {W.shape[1]} inputs but layer {j - 1} gives "
                                      f"{self.layers[j - 1][0].shape[0]}")
            if not (np.isfinite(W).all() and np.isfinite(b).all()):
                raise PolicyFileError(f"layer {j} holds non-finite weights")
        self.obs_dim = self.layers[0][0].shape[1]
        self.act_dim = self.layers[-1][0].shape[0]

    @property
    def sizes(self) -> list[int]:
        return [self.obs_dim] + [W.shape[0] for W, _ in self.layers]

    def __call__(self, obs) -> np.ndarray:
        """obs (obs_dim,) or (n, obs_dim) -> actions in [-1, 1], same leading shape, float32."""
        x = np.asarray(obs, dtype=np.float32)
        single = x.ndim == 1
        if x.shape[-1] != self.obs_dim or x.ndim > 2:
            raise ValueError(f"observation must have shape ({self.obs_dim},) or (n, {self.obs_dim}), got {x.shape}")
        h = x.reshape(1, -1) if single else x
        last = len(self.layers) - 1
        for j, (W, b) in enumerate(self.layers):
            h = h @ W.T + b
            h = np.maximum(h, 0.0, out=h) if j < last else np.tanh(h, out=h)
        return h[0] if single else h


@dataclass
class LoadedPolicy:
    actor: NumpyActor
    meta: dict
    path: Path

    @property
    def variant(self) -> str:
        return self.meta["variant"]

    def trained_slope_range_deg(self, cfg: dict) -> tuple[float, float, str]:
        """(lo, hi, where it comes from): the card's `trained_ranges.slope_deg`; a card without it
        (exported before the field existed) was trained on the episode range of its training
        config (alpha_min_deg, alpha_max_deg), which `cfg` is when the config hashes agree. With
        another config that range is an assumption, and `where` says so."""
        rng = self.meta.get("trained_ranges", {}).get("slope_deg")
        if rng is not None:
            ok = (isinstance(rng, list) and len(rng) == 2
                  and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in rng)
                  and rng[0] < rng[1])
            if not ok:
                raise PolicyFileError(f"{self.path / META_FILE}: trained_ranges.slope_deg = {rng!r}; "
                                      "expected [lo, hi] degrees, lo < hi")
            return float(rng[0]), float(rng[1]), "policy card (trained_ranges.slope_deg)"
        ep = cfg["paper"]["episode"]
        lo, hi = float(ep["alpha_min_deg"]), float(ep["alpha_max_deg"])
        if self.config_matches(cfg):
            return lo, hi, "training config (alpha_min_deg/alpha_max_deg; config hash matches the card)"
        return lo, hi, ("this node's config (alpha_min_deg/alpha_max_deg): the card states no trained range "
                        "and was trained with another config")


    def _trained_with(self):
        tw = self.meta.get("trained_with") or {}

        def num(v):
            return v if isinstance(v, (int, float)) and not isinstance(v, bool) else None
        margin, per_deg, free = (num(tw.get(k)) for k in ("r_success_pitch_margin_deg", "r_tilt_per_deg",
                                                          "r_tilt_free_deg"))
        tilt = (per_deg, free) if per_deg is not None and free is not None else None
        return margin, tilt

    def config_matches(self, cfg: dict) -> bool:
        """The card's config hash names `cfg` up to training-only settings (task.config.hash_matches;
        the card's `trained_with` gives the pitch margin the actor was trained with), or names it as
        it was before a later simulator change (task.config.sim_change_note)."""
        margin, tilt = self._trained_with()
        h = self.meta.get("config_hash")
        return hash_matches(h, cfg, margin, tilt) or sim_change_note(h, cfg, margin, tilt) is not None

    def observation_mismatch(self, cfg: dict) -> str | None:
        """Why this actor would see its observation scaled otherwise under `cfg` than in training,
        or None. The card's `observation.normalisers` (every constant build_observation scales by)
        against `cfg`'s; a card from before that record: its trained slope range, over which alpha
        is normalised, against `cfg`'s alpha_min_deg / alpha_max_deg. Other differences of the
        parameter file (the reward, the simulator) leave what the actor sees as it was."""
        from lhd_loading_ros.task.observation import normaliser_differences
        from lhd_loading_ros.task.params import TaskParams

        own = own_config(self.path)          # the file `lhd ship` copies next to such an actor
        hint = ("; run it with the parameter file it was trained with (config hash "
                f"{str(self.meta.get('config_hash', '?'))[:12]}; "
                + (f"shipped with it: --config {own}, or the nodes' `config` parameter)" if own else
                   "e.g. --config, or the nodes' `config` parameter)"))
        rec = (self.meta.get("observation") or {}).get("normalisers")
        if isinstance(rec, dict) and rec:
            bad = [k for k, v in rec.items() if isinstance(v, bool) or not isinstance(v, (int, float))
                   or not math.isfinite(v)]
            if bad:
                raise PolicyFileError(f"{self.path / META_FILE}: observation.normalisers {', '.join(bad)} are not "
                                      "finite numbers")
            diffs = normaliser_differences(rec, TaskParams.from_config(cfg))
            if not diffs:
                return None
            ep = cfg["paper"]["episode"]
            rng = (self.meta.get("trained_ranges") or {}).get("slope_deg")
            piles = ""
            if isinstance(rng, list) and len(rng) == 2 and not (
                    math.isclose(float(rng[0]), float(ep["alpha_min_deg"]))
                    and math.isclose(float(rng[1]), float(ep["alpha_max_deg"]))):
                piles = (f" (it was trained on {float(rng[0]):g}-{float(rng[1]):g} deg piles, this file's are "
                         f"{float(ep['alpha_min_deg']):g}-{float(ep['alpha_max_deg']):g} deg)")
            return (f"policy {self.path} was trained with another observation scaling than this parameter file "
                    f"gives{piles}: " + ", ".join(f"{k} {a:.6g} in training, {b:.6g} here" for k, a, b in diffs) + hint)
        lo, hi, _ = self.trained_slope_range_deg(cfg)
        ep = cfg["paper"]["episode"]
        if "slope_deg" in (self.meta.get("trained_ranges") or {}) and (
                not math.isclose(lo, float(ep["alpha_min_deg"])) or not math.isclose(hi, float(ep["alpha_max_deg"]))):
            return (f"policy {self.path} was trained on {lo:g}-{hi:g} deg piles, over which its observation "
                    f"normalises the slope; this parameter file normalises it over "
                    f"{float(ep['alpha_min_deg']):g}-{float(ep['alpha_max_deg']):g} deg" + hint)
        return None

    def action_mismatch(self, cfg: dict) -> str | None:
        """Why one action of this actor would command the machine otherwise under `cfg` than in
        training, or None: the card's `action.actuator_low/high` (the rad/s that -1 and +1 map to)
        against `cfg`'s paper.control ranges, and for RLD the hybrid filter's threshold, which it
        was trained through. A card from before a record is not judged on it. A review
        (2026-11-28) set wheels_max 2.7 -> 2.16 to model a slower machine: accepted silently, every
        wheel command 20 % slow (RLD success 0.75, RLC 0.375). A slower machine is the machine's
        property (randomization.drive_gain_*, `lhd eval --stress slow_drive`), not the controller's
        scaling."""
        from lhd_loading_ros.task.params import TaskParams

        p = TaskParams.from_config(cfg)
        act = self.meta.get("action") or {}
        diffs = []
        for key, names in (("actuator_low", ("wheels_min", "boom_min", "bucket_min")),
                           ("actuator_high", ("wheels_max", "boom_max", "bucket_max"))):
            rec = act.get(key)
            if rec is None:
                continue
            if not (isinstance(rec, list) and len(rec) == 3 and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in rec)):
                raise PolicyFileError(f"{self.path / META_FILE}: action.{key} = {rec!r}; expected 3 finite numbers "
                                      "(rad/s of wheels, boom, bucket)")
            for n, a in zip(names, rec):
                b = float(getattr(p, n))
                if not math.isclose(float(a), b, rel_tol=1e-9, abs_tol=1e-12):
                    diffs.append((f"paper.control.{n}", float(a), b))
        thr = (self.meta.get("filters") or {}).get("rld_threshold")
        if self.variant == "rld" and isinstance(thr, (int, float)) and not isinstance(thr, bool) and not math.isclose(
                float(thr), float(p.rld_threshold), rel_tol=1e-9, abs_tol=1e-12):
            diffs.append(("task.rld_threshold", float(thr), float(p.rld_threshold)))
        if not diffs:
            return None
        own = own_config(self.path)
        return (f"policy {self.path} was trained with its actions mapped otherwise than this parameter file maps "
                "them: " + ", ".join(f"{k} {a:.6g} in training, {b:.6g} here" for k, a, b in diffs)
                + "; the same action would command the machine otherwise. Keep the trained mapping (a slower or "
                  "faster machine is the machine's own: randomization.drive_gain_* / hydraulic_gain_*, lhd eval "
                  "--stress slow_drive | slow_hydraulics)"
                + (f"; its own parameter file: --config {own}" if own else ""))

    def check_config(self, cfg: dict) -> "LoadedPolicy":
        """Raise PolicyFileError when the actor would see another observation scaling under `cfg`
        (observation_mismatch), or its actions would map to other actuator speeds
        (action_mismatch); return self."""
        why = self.observation_mismatch(cfg) or self.action_mismatch(cfg)
        if why is not None:
            raise PolicyFileError(why)
        return self

    def sim_change_note(self, cfg: dict) -> str | None:
        """task.config.sim_change_note for this card: trained on the simulator before a change."""
        margin, tilt = self._trained_with()
        return sim_change_note(self.meta.get("config_hash"), cfg, margin, tilt)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# The fields of policy.json that decide how an actor is run (LoadedPolicy reads them: the action mapping and
# its filter, the observation's scaling, the slopes it accepts, the parameter files it runs under); card_sha256
# seals them. The rest (evaluation figures, seed, steps, DDPG settings) is the card's record, not its behaviour.
SEALED_FIELDS = ("format", "variant", "architecture", "observation", "action", "filters", "trained_ranges",
                 "config_hash", "trained_with", "actor_sha256")


def card_digest(meta: dict) -> str:
    """SHA-256 of the sealed fields of a card (canonical JSON: sorted keys, no spaces)."""
    sealed = {k: meta[k] for k in SEALED_FIELDS if k in meta}
    text = json.dumps(sealed, sort_keys=True, separators=(",", ":"), default=_json_default)
    return hashlib.sha256(text.encode()).hexdigest()


def seal_card(directory) -> str:
    """Write card_sha256 into <directory>/policy.json for its present fields; return the digest. For a card
    edited on purpose (the edit is then the author's to document); save_policy seals every card it writes."""
    d = Path(directory)
    meta = json.loads((d / META_FILE).read_text())
    meta["card_sha256"] = card_digest(meta)
    _write_card(d, meta)
    return meta["card_sha256"]


def _write_card(d: Path, meta: dict) -> None:
    """policy.json, written whole or not at all (a temporary file, then a rename)."""
    tmp = d / (META_FILE + ".tmp")
    tmp.write_text(json.dumps(meta, indent=2, sort_keys=True, default=_json_default) + "\n")
    tmp.replace(d / META_FILE)


def save_policy(directory, layers: list[tuple[np.ndarray, np.ndarray]], meta: dict) -> Path:
    """Write actor.npz and policy.json into `directory` (created); return the directory."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    actor = NumpyActor(layers)     # validates shapes and finiteness
    arrays = {}
    for j, (W, b) in enumerate(actor.layers):
        arrays[f"W{j}"], arrays[f"b{j}"] = W, b
    tmp = d / (ACTOR_FILE + ".tmp.npz")
    np.savez(tmp, **arrays)
    tmp.replace(d / ACTOR_FILE)
    full = dict(meta)
    full.update({
        "format": FORMAT,
        "architecture": {"sizes": actor.sizes, "hidden_activation": "relu", "output_activation": "tanh",
                         "dtype": "float32", "layout": "y = x @ W.T + b per layer"},
        "actor_sha256": _sha256(d / ACTOR_FILE),
    })
    full["card_sha256"] = card_digest(full)
    _write_card(d, full)
    return d


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


# The actors the real-machine stack (`lhd up real`, `lhd up twin`, real_machine.launch.py) runs for
# --controller rld / rlc when no --policy is given: the ones that pass `lhd eval --stress machine`
# (placed by hand, from rest, on a rough pile: how an attempt on the machine goes). The main job
# (`lhd demo`, `lhd up sim`) keeps policies/rld and policies/rlc, the paper's protocol, which load every
# pile of the paper's protocol but keep 0.61 / 0.70 of the machine case (docs/real_machine.md "Which actor on the machine",
# docs/evidence/machine_case/). Both ship their own parameter file (the 10-35 deg piles' normalisers).
# RLD: rld_drift_confirm from 2026-12-01 (twenty-fourth session) to 2026-12-02: with the drift flags the bridge gives at a start
# from rest it keeps 28-30 of 30 attempts on every slope of 10-35 deg where rld_machine (2026-11-29 to 2026-11-30;
# rld_gains before it) keeps 14-23 on 10-15 deg piles, and 8 of 8 in the twin on 12 and 14 deg piles against
# rld_machine's 5 (docs/real_machine.md "Which actor on the machine", docs/evidence/drift_confirm/).
# RLD: rld_drift_confirm_margin8 since 2026-12-02 (thirty-sixth session): the same recipe with r_success paid only from
# 28 kg; it succeeds in every slope-error cell the nodes accept with the mass within 13 % (issue 14's bound;
# rld_drift_confirm 75 % on a 30 deg pile told 15 deg), keeps 297 of 300 attempts on 10-35 deg with the bridge's flags
# (293), and 63 of the 64 attempts of its digital-twin runs on 2 cores (docs/real_machine.md "Which actor on the
# machine", docs/evidence/margin8/).
MACHINE_ACTORS = {"rld": "rld_drift_confirm_margin8", "rlc": "rlc_gains"}
# The slopes each machine actor keeps >= 0.9 of the machine case on (30 episodes a slope,
# docs/evidence/machine_case/slopes.txt, docs/evidence/drift_confirm/machine_case_slopes.txt,
# docs/evidence/margin8/machine_case_slopes_rld.txt): rld_drift_confirm_margin8 28-30/30 on every slope of 10-35 deg
# with the bridge's drift flags (rld_drift_confirm 28-30/30; rld_machine 24/30 on 10 and 12 deg: it was armed on
# 14-35); rlc_gains 30/30 on 10-14 deg, 27/30 on 32.5 and 35. The real stack passes them to the supervisor
# (slope_limits_deg), which arms only inside both them and the card's range (the RLD's 10-40 deg: 35-40 deg piles are
# not in the machine case's table, and 40 deg piles are its weak slope, 0.65 / 0.35).
MACHINE_SLOPE_LIMITS_DEG = {"rld": (10.0, 35.0), "rlc": (10.0, 35.0)}


def own_config(policy_dir) -> Path | None:
    """The parameter file an actor ships with (lhd ship copies it: <policy_dir>/lhd_params.yaml), or None."""
    f = Path(policy_dir) / "lhd_params.yaml"
    return f if f.is_file() else None


def default_policy_dir(variant: str = "rld") -> Path:
    """policies/<variant> of the source tree, else the installed share copy."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / "policies" / variant
        if (cand / "policy.json").is_file():
            return cand
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory("lhd_loading_ros")) / "policies" / variant
    except Exception:  # noqa: BLE001 - no ament index here
        return Path("policies") / variant


def load_policy(directory) -> LoadedPolicy:
    """Load and check a policy directory. Raises PolicyFileError naming what is wrong."""
    d = Path(directory)
    if not d.is_dir():
        what = "is a file, not a directory" if d.exists() else "does not exist"
        raise PolicyFileError(f"policy directory {d} {what}; expected a directory with {ACTOR_FILE} "
                              f"and {META_FILE} (see policies/README.md)")
    for name in (ACTOR_FILE, META_FILE):
        if not (d / name).is_file():
            raise PolicyFileError(f"policy directory {d} has no {name}; expected {ACTOR_FILE} and {META_FILE}")
    try:
        meta = json.loads((d / META_FILE).read_text())
    except json.JSONDecodeError as exc:
        raise PolicyFileError(f"{d / META_FILE} is not valid JSON: {exc}") from exc
    if meta.get("format") != FORMAT:
        raise PolicyFileError(f"{d / META_FILE}: format {meta.get('format')!r}, expected {FORMAT!r}")
    if meta.get("variant") not in ("rld", "rlc"):
        raise PolicyFileError(f"{d / META_FILE}: variant {meta.get('variant')!r}, expected 'rld' or 'rlc'")
    digest = _sha256(d / ACTOR_FILE)
    if meta.get("actor_sha256") != digest:
        raise PolicyFileError(f"{d / ACTOR_FILE} does not match the SHA-256 recorded in {META_FILE} "
                              "(file replaced or corrupted)")
    if "card_sha256" in meta and meta["card_sha256"] != card_digest(meta):
        raise PolicyFileError(f"{d / META_FILE} was changed after export: its fields {', '.join(SEALED_FIELDS[1:])} "
                              "no longer match the card_sha256 written with them, and the policy node would run the "
                              "actor otherwise than it was trained (another action mapping, scaling or slope range); "
                              "export it again (lhd ship / lhd train), or restore the card from the export")
    with np.load(d / ACTOR_FILE, allow_pickle=False) as z:
        n = len([k for k in z.files if k.startswith("W")])
        try:
            layers = [(z[f"W{j}"], z[f"b{j}"]) for j in range(n)]
        except KeyError as exc:
            raise PolicyFileError(f"{d / ACTOR_FILE} lacks array {exc}; expected W0, b0, W1, b1, ...") from exc
    actor = NumpyActor(layers)
    if actor.sizes != meta["architecture"]["sizes"]:
        raise PolicyFileError(f"{d}: weights have sizes {actor.sizes}, {META_FILE} says {meta['architecture']['sizes']}")
    if actor.sizes[0] != OBS_SIZE or actor.sizes[-1] != ACT_SIZE:     # else a shape error deep in the first step
        raise PolicyFileError(f"{d}: the actor maps {actor.sizes[0]} inputs to {actor.sizes[-1]} outputs (sizes "
                              f"{actor.sizes}); expected {OBS_SIZE} (the observation) to {ACT_SIZE} (wheels, boom, "
                              "bucket)")
    return LoadedPolicy(actor, meta, d)
