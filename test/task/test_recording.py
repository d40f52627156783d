"""The recorder's decisions (task/recording.py), with a hand-driven clock: when an attempt's bag
opens and closes, a latched status history that must not open a bag, the folder of an attempt
whose number was used before, the topics selected."""

import pytest

from lhd_loading_ros.task.recording import (SETTLE_S, RecordingPlan, attempt_number, bag_folder, bag_name,
                                            next_free_attempt, topic_selected)


def acts(plan, now):
    return [(a.kind, a.attempt, a.why) for a in plan.due(now)]


def test_armed_opens_after_the_settle_time_and_the_end_closes_after_the_post_roll():
    plan = RecordingPlan(post_roll_s=1.0)
    plan.on_status("armed", 3, 10.0)
    assert acts(plan, 10.0) == []                          # a history burst could still cancel it
    assert acts(plan, 10.0 + SETTLE_S) == [("open", 3, "armed")]
    plan.on_status("running", 3, 11.0)                    # the same attempt goes on: nothing to do
    assert acts(plan, 11.0) == []
    plan.on_status("success", 3, 14.0)
    assert acts(plan, 14.99) == []                         # post-roll: the stop, the machine at rest
    assert acts(plan, 15.0) == [("close", 3, "post-roll after success")]
    plan.on_status("success", 3, 15.5)                    # the supervisor repeats its state at 2 Hz
    assert acts(plan, 17.0) == [] and not plan.is_recording


@pytest.mark.parametrize("end", ["success", "failure", "timeout", "estop", "lost_input", "aborted"])
def test_every_end_state_closes(end):
    plan = RecordingPlan(post_roll_s=0.5)
    plan.on_status("running", 1, 0.0)                     # armed missed: running opens too
    assert acts(plan, 0.2) == [("open", 1, "running")]
    plan.on_status(end, 1, 1.0)
    assert acts(plan, 1.5) == [("close", 1, f"post-roll after {end}")]


def test_a_latched_history_of_an_attempt_that_is_over_opens_nothing():
    """A recorder that subscribes late gets the status history in a burst."""
    plan = RecordingPlan()
    for st in ("armed", "running", "timeout"):
        plan.on_status(st, 6, 5.0)
    assert acts(plan, 6.0) == []
    # ...but the attempt that is running now, at the end of the burst, is recorded
    for st, n in (("armed", 6), ("running", 6), ("success", 6), ("armed", 7)):
        plan.on_status(st, n, 7.0)
    assert acts(plan, 7.0 + SETTLE_S) == [("open", 7, "armed")]


def test_the_next_attempt_armed_during_the_post_roll_closes_at_once():
    plan = RecordingPlan(post_roll_s=2.0)
    plan.on_status("armed", 1, 0.0)
    acts(plan, 0.2)
    plan.on_status("failure", 1, 1.0)
    plan.on_status("armed", 2, 1.5)
    assert acts(plan, 1.5) == [("close", 1, "attempt 2 armed")]
    assert acts(plan, 1.5 + SETTLE_S) == [("open", 2, "armed")]


def test_idle_or_another_attempts_end_close_the_open_bag():
    plan = RecordingPlan(post_roll_s=1.0)
    plan.on_status("running", 4, 0.0)
    acts(plan, 0.2)
    plan.on_status("idle", 4, 1.0)              # a restarted supervisor: no end state was published
    assert acts(plan, 2.0) == [("close", 4, "post-roll after state 'idle' (the attempt ended without an end state)")]
    plan.on_status("running", 5, 3.0)
    acts(plan, 3.2)
    plan.on_status("timeout", 9, 4.0)
    assert acts(plan, 5.0) == [("close", 5, "post-roll after attempt 9 timeout (another attempt)")]


def test_the_same_number_armed_again_after_its_end_is_a_new_bag():
    """A supervisor restarted after attempt 2 counts from 2 again: the recorder closes the
    first bag and opens another (bag_folder then gives it a suffix)."""
    plan = RecordingPlan(post_roll_s=5.0)
    plan.on_status("armed", 2, 0.0)
    acts(plan, 0.2)
    plan.on_status("success", 2, 1.0)
    plan.on_status("armed", 2, 2.0)
    assert acts(plan, 2.0 + SETTLE_S) == [("close", 2, "attempt 2 armed again"), ("open", 2, "armed")]


def test_shutdown_closes_what_is_open_and_forgets_a_pending_open():
    plan = RecordingPlan()
    plan.on_status("armed", 1, 0.0)
    assert plan.shutdown() == []
    plan.on_status("armed", 1, 1.0)
    acts(plan, 1.2)
    assert [(a.kind, a.why) for a in plan.shutdown()] == [("close", "shutdown")]


def test_attempt_numbers():
    assert attempt_number({"episode": "3"}) == 3
    assert attempt_number({"episode": "3.0"}) == 3
    assert attempt_number({"episode": 0}) == 0
    for bad in ("", "x", "-1", "2.5", "nan", "inf", None):
        assert attempt_number({"episode": bad}) is None
    assert attempt_number({}) is None
    assert bag_name(7) == "attempt_0007" and bag_name(12345) == "attempt_12345"
    with pytest.raises(ValueError):
        bag_name(-1)


def test_an_existing_folder_is_never_reused(tmp_path):
    path, note = bag_folder(tmp_path, 3)
    assert path == tmp_path / "bags" / "attempt_0003" and note is None
    path.mkdir(parents=True)
    (tmp_path / "bags" / "attempt_0003_2").mkdir()
    path, note = bag_folder(tmp_path, 3)
    assert path == tmp_path / "bags" / "attempt_0003_3"
    assert "attempt_0003 already exists" in note and "attempt_0003_3" in note


def test_next_free_attempt(tmp_path):
    assert next_free_attempt(tmp_path) == 1
    for name in ("attempt_0002", "attempt_0009_2", "notes", "attempt_x"):
        (tmp_path / "bags" / name).mkdir(parents=True)
    assert next_free_attempt(tmp_path) == 10


def test_topics_selected():
    assert topic_selected("/lhd/cmd", "/lhd") and topic_selected("/lhd/pile/slope", "/lhd/")
    assert not topic_selected("/lhd2/cmd", "/lhd")            # another machine's prefix
    assert not topic_selected("/joy", "/lhd") and topic_selected("/joy", "/lhd", ("/joy", "/diagnostics"))
    assert topic_selected("/lhd2/odom", "/lhd2")
