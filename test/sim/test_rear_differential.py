"""The paper's drive (machine.rear_differential: 1): "the rear wheels share a single motor and are
connected to a differential, whilst each front wheel has an independent motor". An open
differential gives both rear wheels the same torque, so a rear wheel without grip takes the
other's drive with it; separate motors (rear_differential: 0, the model before 2026-11-26) keep
driving the wheel that grips. Expectations by hand from the machine's parameters."""
from __future__ import annotations

import copy
import pytest

from lhd_loading_ros.task.config import config_hash, load_config
from lhd_sim_node.simulator import LhdSimulator

from test_drift_tempo import drive_against


@pytest.fixture(scope="module")
def cfg():
    return load_config()


def with_diff(cfg, on: int, **machine):
    c = copy.deepcopy(cfg)
    c["machine"]["rear_differential"] = on
    c["machine"].update(machine)
    return c


def test_the_shipped_config_is_the_papers_drive(cfg):
    assert cfg["machine"]["rear_differential"] == 1
    m = LhdSimulator(cfg).model
    names = [m.actuator(i).name for i in range(m.nu)]
    assert sorted(names) == ["boom", "bucket", "wheel_fl", "wheel_fr", "wheel_r"]
    t = m.tendon("drive_r")
    adr, num = int(m.tendon_adr[t.id]), int(m.tendon_num[t.id])
    joints = {m.joint(int(m.wrap_objid[k])).name: float(m.wrap_prm[k]) for k in range(adr, adr + num)}
    assert joints == {"motor_r": 1.0, "wheel_rl": -0.5, "wheel_rr": -0.5}   # rotor at the mean rear speed
    tau, kv, arm = (cfg["machine"][k] for k in ("wheel_torque_limit", "wheel_kv", "motor_armature"))
    assert float(m.tendon_frictionloss[t.id]) == pytest.approx(2 * tau)   # tau to each rear wheel
    assert float(m.actuator_gainprm[m.actuator("wheel_r").id, 0]) == pytest.approx(2 * kv)
    assert float(m.dof_armature[m.jnt_dofadr[m.joint("motor_r").id]]) == pytest.approx(2 * arm)
    # four motors before: the old model and its hash stay what they were
    old = with_diff(cfg, 0)
    assert LhdSimulator(old).model.nu == 6
    legacy = copy.deepcopy(cfg)
    del legacy["machine"]["rear_differential"]
    assert config_hash(old) == config_hash(legacy) != config_hash(cfg)


def test_both_drives_push_with_four_torque_limits(cfg):
    """Tyres that cannot slip (mu = 2): with the differential the largest push is still
    (2 tau [front motors] + 2 tau [the rear motor's 2 tau split in two]) / r = 876 N."""
    for on in (0, 1):
        c = with_diff(cfg, on, wheel_friction=2.0)
        F = 4 * c["machine"]["wheel_torque_limit"] / c["machine"]["wheel_radius"]
        assert drive_against(c, 0.9 * F)[0] > 0.05, on
        assert abs(drive_against(c, 1.1 * F)[0]) < 0.005, on


def _one_rear_wheel_on_ice():
    """Patch LhdSimulator so the left rear tyre has (almost) no grip."""
    orig = LhdSimulator.__init__

    def init(self, cfg, **kw):
        orig(self, cfg, **kw)
        self.model.geom_friction[self.model.geom("wheel_rl").id, 0] = 0.01
    return init


def test_a_rear_wheel_on_ice_takes_the_other_ones_drive(cfg, monkeypatch):
    """Left rear tyre on ice (mu 0.01), the others gripping (mu 2), a resistance R on the bucket.
    Separate motors: the front motors (2 tau) and the right rear one (tau) push: 3 tau / r = 657 N.
    Open differential: the rear motor can put no more torque into the right wheel than the free
    left wheel takes (about none), so only the front motors push: 2 tau / r = 438 N. A resistance
    of 550 N (between the two) is overcome with separate motors and stalls the differential
    drive, whose left rear wheel then spins."""
    tau, r = cfg["machine"]["wheel_torque_limit"], cfg["machine"]["wheel_radius"]
    R = 0.5 * (2 * tau / r + 3 * tau / r)
    monkeypatch.setattr(LhdSimulator, "__init__", _one_rear_wheel_on_ice())
    dx_sep, _ = drive_against(with_diff(cfg, 0, wheel_friction=2.0), R)
    dx_diff, rim = drive_against(with_diff(cfg, 1, wheel_friction=2.0), R)
    assert dx_sep > 0.05, dx_sep                 # separate motors keep driving
    assert abs(dx_diff) < 0.01, dx_diff          # the differential drive stalls
    assert abs(rim[2]) > 0.05, rim               # ... with the wheel on ice spinning (rl: index 2 of WHEELS)
    assert abs(rim[3]) < 0.02, rim               # and the gripping rear wheel held
