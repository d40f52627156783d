"""The policy card's seal (card_sha256): a card edited by hand after export is refused, its record may change,
a card from before the seal still loads, and every shipped card carries a seal that matches it. The digest is
recomputed here from the documented rule (SHA-256 of the sealed fields as canonical JSON), not with card_digest."""
import hashlib
import json
import shutil
from pathlib import Path

import pytest

from lhd_loading_ros.policy.actor_file import META_FILE, PolicyFileError, load_policy, seal_card

ROOT = Path(__file__).resolve().parents[2]
# the fields that decide how an actor is run, as docs/training.md "Export format" lists them
SEALED = ("format", "variant", "architecture", "observation", "action", "filters", "trained_ranges", "config_hash",
          "trained_with", "actor_sha256")


def digest_by_hand(meta):
    text = json.dumps({k: meta[k] for k in SEALED if k in meta}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def shipped_dirs():
    return [d for d in sorted((ROOT / "policies").iterdir()) if (d / META_FILE).is_file()]


def test_every_shipped_card_is_sealed_and_its_seal_matches():
    dirs = shipped_dirs()
    assert len(dirs) >= 28
    for d in dirs:
        meta = json.loads((d / META_FILE).read_text())
        assert meta.get("card_sha256") == digest_by_hand(meta), d.name
        load_policy(d)


@pytest.fixture
def card(tmp_path):
    d = tmp_path / "rld"
    shutil.copytree(ROOT / "policies" / "rld", d)
    return d


def edit(d, change):
    meta = json.loads((d / META_FILE).read_text())
    change(meta)
    (d / META_FILE).write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return meta


@pytest.mark.parametrize("what, change", [
    ("variant rld -> rlc", lambda m: m.update(variant="rlc")),
    ("slope range widened", lambda m: m["trained_ranges"].update(slope_deg=[5.0, 45.0])),
    ("an observation normaliser", lambda m: m["observation"].update(high=[2.0] * 12)),
    ("the RLD threshold", lambda m: m["filters"].update(rld_threshold=0.3)),
    ("the config hash", lambda m: m.update(config_hash="0" * 16)),
    ("the seal removed and replaced by another", lambda m: m.update(card_sha256="f" * 64)),
])
def test_a_card_edited_after_export_is_refused_and_says_so(card, what, change):
    assert load_policy(card).variant == "rld"
    edit(card, change)
    with pytest.raises(PolicyFileError, match="was changed after export") as e:
        load_policy(card)
    assert "export it again" in str(e.value), what


def test_the_record_may_change_and_an_unsealed_card_loads(card):
    before = json.loads((card / META_FILE).read_text())["card_sha256"]
    edit(card, lambda m: (m["evaluation"].update(success_rate=0.5), m.update(seed=99)))   # the record, not the behaviour
    assert load_policy(card).meta["seed"] == 99
    meta = edit(card, lambda m: (m.pop("card_sha256"), m.update(variant="rlc")))   # a card from before the seal
    assert "card_sha256" not in meta and load_policy(card).variant == "rlc"
    # sealing it again is a deliberate re-export of the card: it loads, with another seal
    assert seal_card(card) != before and load_policy(card).variant == "rlc"
    assert json.loads((card / META_FILE).read_text())["card_sha256"] == digest_by_hand(meta)


def test_an_exported_card_is_sealed_by_the_documented_rule(cfg, tmp_path):
    from lhd_loading_ros.learning.ddpg import DdpgAgent, DdpgConfig
    from lhd_loading_ros.learning.export import export_actor

    agent = DdpgAgent(DdpgConfig.from_config(cfg), seed=0)
    d = export_actor(tmp_path / "p", agent.actor, cfg, {"variant": "rlc", "seed": 0, "steps": 0})
    meta = json.loads((d / META_FILE).read_text())
    assert meta["card_sha256"] == digest_by_hand(meta) and load_policy(d).variant == "rlc"
