"""The estimation-error arithmetic of `lhd up twin` (pure functions, no nodes): what the stack's
planar motion leaves out of the final pitch, computed against a hand-made rotation."""
import math

import numpy as np
import pytest

from lhd_loading_ros.cli.up_twin import latest_before, pitch_dropped_deg
from lhd_loading_ros.task.kinematics import ArmKinematics


def quat_about(axis, angle):
    """(w, x, y, z) of a rotation by `angle` about a unit axis."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return (math.cos(angle / 2), *(math.sin(angle / 2) * a))


@pytest.fixture
def kin(cfg):
    return ArmKinematics.from_config(cfg)


JOINTS = {"boom": (-0.3, 0.0), "bucket": (0.4, 0.0)}


@pytest.mark.parametrize("theta_deg", [-3.0, -0.7, 0.0, 0.5, 2.5])
def test_a_pure_pitch_of_the_machine_is_what_planar_motion_drops(kin, theta_deg):
    # the arm turns about the machine's y axis, so a machine pitched by theta about y turns the tip
    # frame by theta too: the tip pitch, atan2(R[2,0], R[0,0]), changes by -theta (a rotation by
    # +theta about y maps x to (cos, 0, -sin)), whatever the joint angles
    th = math.radians(theta_deg)
    pose = (0.0, (-1.0, 0.0, 0.137), quat_about((0, 1, 0), th))
    assert pitch_dropped_deg(kin, pose, JOINTS) == pytest.approx(-theta_deg, abs=1e-9)
    other = {"boom": (-0.1, 0.0), "bucket": (0.9, 0.0)}
    assert pitch_dropped_deg(kin, pose, other) == pytest.approx(-theta_deg, abs=1e-9)


def test_heading_alone_drops_nothing(kin):
    pose = (0.0, (-1.0, 0.2, 0.137), quat_about((0, 0, 1), math.radians(7.0)))
    assert pitch_dropped_deg(kin, pose, JOINTS) == pytest.approx(0.0, abs=1e-9)


def test_latest_before_picks_the_last_entry_at_or_before():
    series = [(1.0, "a"), (2.0, "b"), (3.0, "c")]
    assert latest_before(series, 0.5) is None
    assert latest_before(series, 2.0) == (2.0, "b")
    assert latest_before(series, 2.9) == (2.0, "b")
    assert latest_before(series, 9.0) == (3.0, "c")


@pytest.mark.parametrize("heading_deg, theta_deg", [(20.0, 3.0), (-35.0, -2.0)])
def test_pitch_and_heading_together(kin, heading_deg, theta_deg):
    """Independently: the arm turns the tip frame about the machine's y axis by its own angle a
    (-(the tip pitch of the level, unturned machine)); the machine's rotation Rz(heading) Ry(theta)
    composes with it, and the project's pitch is atan2(R[2,0], R[0,0]) of the result. What planar
    motion drops is that pitch minus the one of Rz(heading) Ry(a)."""
    def rz(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])

    def ry(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])

    def pitch(R):
        return math.atan2(R[2, 0], R[0, 0])

    a = -kin.tip_and_bottom(np.zeros(3), np.eye(3), JOINTS["boom"][0], JOINTS["bucket"][0])[1]
    psi, th = math.radians(heading_deg), math.radians(theta_deg)
    expect = math.degrees(pitch(rz(psi) @ ry(th) @ ry(a)) - pitch(rz(psi) @ ry(a)))
    w, x, y, z = quat_about((0, 0, 1), psi)
    qz = np.array([w, x, y, z])
    qy = np.array(quat_about((0, 1, 0), th))
    # Hamilton product qz * qy: the rotation Rz(psi) Ry(theta)
    q = (qz[0] * qy[0] - qz[1:] @ qy[1:], *(qz[0] * qy[1:] + qy[0] * qz[1:] + np.cross(qz[1:], qy[1:])))
    pose = (0.0, (-1.0, 0.1, 0.137), q)
    assert pitch_dropped_deg(kin, pose, JOINTS) == pytest.approx(expect, abs=1e-9)
    assert abs(expect + theta_deg) < 0.1 * abs(theta_deg)      # about -theta, not exactly (heading couples in)


def test_success_with_the_machine_pitch_rejudges_weighed_attempts_by_the_paper_test():
    """Hand-made records: a success whose corrected pitch falls under 40 deg no longer counts, an
    SL 0 timeout whose corrected pitch rises above it does, a light bucket stays a failure whatever
    its pitch; the denominator is the stack's (aborted and unweighed attempts left out, failures
    and e-stops in); the summary names the turned ones."""
    from lhd_loading_ros.cli.up_twin import format_errors, error_summary, machine_pitch_success

    def rec(n, outcome, mass, phi, corrected):
        return {"attempt": n, "outcome": outcome, "mass_csv_kg": mass, "phi_final_deg": phi,
                "phi_thresh_deg": 40.0, "phi_dropped_deg": None if corrected is None else corrected - phi,
                "phi_final_corrected_deg": corrected}
    records = [rec(1, "success", 35.0, 46.97, 37.39),      # lenient stack: fails with the machine's pitch
               rec(2, "success", 30.0, 43.0, 42.9),
               rec(3, "timeout", 25.0, 39.8, 40.3),        # SL 0 by the stack, SL 3 with the pitch
               rec(4, "success", 19.0, 45.0, 45.0),        # < 20 kg: not a success either way
               rec(5, "aborted", None, float("nan"), None),
               rec(6, "success", None, 44.0, 44.0),        # not weighed: not counted (as by the stack)
               rec(7, "failure", 12.0, 10.0, None),        # restricted zone: counted, a failure
               rec(8, "estop", None, float("nan"), None)]  # e-stop: counted, a failure
    assert machine_pitch_success(records) == (2, 6)
    assert machine_pitch_success([records[4], records[6]]) is None
    for r in records:
        r.update({"vx_rms": None, "vx_n": 0, "slope_truth_deg": 30.0, "alpha_est_deg": None, "alpha_err_deg": None,
                  "x_max_est_m": None, "x_max_truth_m": None, "x_max_err_m": None, "mass_truth_kg": None,
                  "mass_err_kg": None, "drift_agree_front": None, "drift_agree_rear": None})
    text = format_errors(records, error_summary(records))
    assert "turns: #1, #3" in text and "2 / 6 = 0.33" in text


def test_odometry_age_by_hand():
    """The median and the oldest age (ms) of the odometry stamped within the attempt only."""
    from lhd_loading_ros.cli.up_twin import odom_age_ms

    ages = [(0.9, 0.500), (1.0, 0.020), (1.1, 0.030), (1.2, 0.160), (2.1, 0.900)]
    p50, mx = odom_age_ms(ages, 1.0, 2.0)
    assert p50 == pytest.approx(30.0) and mx == pytest.approx(160.0)
    assert odom_age_ms(ages, 3.0, 4.0) == (None, None)


def test_stack_age_by_hand():
    """The stack's part of the odometry's age: the age less the twin's camera lag of the same image
    (matched by stamp), over the attempt's images that have a lag message."""
    from lhd_loading_ros.cli.up_twin import stack_age_ms

    ages = [(0.9, 0.500), (1.0, 0.020), (1.1, 0.030), (1.2, 0.160), (1.3, 0.050), (2.1, 0.900)]
    lag = {0.9: 0.4, 1.0: 0.005, 1.1: 0.010, 1.2: 0.120}    # none for 1.3 (its lag message was lost)
    p50, mx, cam = stack_age_ms(ages, lag, 1.0, 2.0)
    # stack parts 15, 20, 40 ms; camera lags 5, 10, 120 ms
    assert p50 == pytest.approx(20.0) and mx == pytest.approx(40.0) and cam == pytest.approx(10.0)
    assert stack_age_ms(ages, {}, 1.0, 2.0) == (None, None, None)
    assert stack_age_ms(ages, lag, 3.0, 4.0) == (None, None, None)
