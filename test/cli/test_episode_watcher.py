"""The launcher's reading of /episode (cli/launcher.py EpisodeWatcher): every ended episode the
sim node counted must have been heard, or `lhd up sim` fails naming the ones it missed (it once
exited 0 with one result of two, a starved launcher on a keep-last-10 topic)."""
import pytest

from lhd_loading_ros.cli.launcher import EpisodeWatcher


def status(episode: int, state: str, done: int, all_done: bool = False, loaded: float = 31.5) -> dict:
    """An /episode status as the sim node writes it (DiagnosticStatus values: strings)."""
    kv = {"state": state, "episode": str(episode), "step": "87", "loaded_mass": f"{loaded:.4f}",
          "slope_deg": "25.000", "material": "homogeneous", "episodes_done": str(done), "all_done": str(all_done)}
    if state in ("success", "failure", "timeout"):
        kv.update({"success": "True", "success_level": "3", "return": "41.200", "elapsed_s": "8.70",
                   "front_drift_pct": "0.00", "rear_drift_pct": "2.30", "phi_final_deg": "31.00",
                   "max_tilt_deg": "1.250"})
    return kv


def test_every_end_heard_is_complete_and_the_results_are_the_statuses():
    heard = []
    w = EpisodeWatcher(on_episode=lambda ep, r: heard.append((ep, r.loaded)))
    w.on_status(status(0, "running", 0))
    assert w.done == {"all": False, "heard": True} and not w.results
    w.on_status(status(0, "success", 1, loaded=30.0))
    w.on_status(status(0, "success", 1, loaded=30.0))     # the same end again (a repeated state): one result
    w.on_status(status(1, "running", 1))
    w.on_status(status(1, "timeout", 2, all_done=True, loaded=12.25))
    assert w.done["all"]
    w.check_complete()
    assert heard == [(0, 30.0), (1, 12.25)]
    assert sorted(w.results) == [0, 1] and w.results[1].truncated and w.results[0].reached_end_zone


def test_a_lost_end_is_an_error_naming_the_episode():
    w = EpisodeWatcher()
    w.on_status(status(0, "success", 1))
    # episode 1's end was replaced by episode 2's running statuses before this watcher read it
    w.on_status(status(2, "running", 2))
    w.on_status(status(2, "failure", 3, all_done=True))
    with pytest.raises(RuntimeError) as exc:
        w.check_complete()
    msg = str(exc.value)
    assert "ended 3 episodes" in msg and "heard the end of 2 ([0, 2])" in msg and "episode(s) [1]" in msg


def test_an_aborted_episode_is_not_a_result_and_not_missing():
    """An aborted episode (MuJoCo found the state unstable) has no result and the node does not
    count it; it neither fails the watcher (no result keys) nor counts as missing."""
    w = EpisodeWatcher()
    w.on_status(status(0, "aborted", 0))
    w.on_status(status(1, "success", 1))
    w.on_status(status(2, "success", 2, all_done=True))
    w.check_complete()
    assert sorted(w.results) == [1, 2] and w.aborted == {0}


def test_check_before_the_end_is_refused():
    with pytest.raises(RuntimeError, match="before the sim node's all-done status"):
        EpisodeWatcher().check_complete()
