"""lhd_loading_ros.ros.params on a real rclpy node: the other numeric type accepted, clear
errors, descriptors, runtime changes applied or rejected with a reason (through the node's
parameter services, over DDS, as `ros2 param set` does)."""
import math

import pytest
import rclpy
from rclpy.parameter import Parameter

from lhd_loading_ros.ros.params import Param, Params
from rosutil import init_ros, shutdown_ros, spin_until


@pytest.fixture(scope="module")
def ros():
    init_ros()
    yield
    shutdown_ros()


def make(name, overrides, specs):
    node = rclpy.create_node(name, parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
    return node, Params(node, specs)


def specs(applied):
    return [
        Param("rate_hz", 10.0, "decision rate", lo=0.1, hi=1000.0),
        Param("seed", 0, "first seed", lo=0, hi=2**31 - 1),
        Param("mode", "realtime", "how to step", choices=("realtime", "lockstep")),
        Param("timeout", 0.5, "input timeout", lo=0.01, hi=60.0, on_change=lambda v: applied.append(v)),
        Param("xyz", [0.0, 0.0, 1.0], "a position", length=3),
    ]


def test_other_numeric_type_is_taken_and_stored_in_the_declared_type(ros):
    node, p = make("t_types", {"rate_hz": 20, "seed": 3.0}, specs([]))
    try:
        assert p["rate_hz"] == 20.0 and isinstance(p["rate_hz"], float)
        assert p["seed"] == 3 and isinstance(p["seed"], int)
        assert node.get_parameter("rate_hz").type_ == Parameter.Type.DOUBLE
        assert node.get_parameter("seed").type_ == Parameter.Type.INTEGER
        d = node.describe_parameter("rate_hz")
        assert d.description == "decision rate" and d.read_only
        assert d.floating_point_range[0].from_value == 0.1 and d.floating_point_range[0].to_value == 1000.0
        assert not node.describe_parameter("timeout").read_only
    finally:
        node.destroy_node()


@pytest.mark.parametrize("overrides, needle", [
    ({"rate_hz": 0.0}, "'rate_hz' = 0.0 is invalid: out of range; expected a number in [0.1, 1000.0]"),
    ({"rate_hz": "fast"}, "'rate_hz' = 'fast' is invalid; expected a number"),
    ({"seed": 2.5}, "'seed' = 2.5 is invalid; expected an integer"),
    ({"seed": True}, "'seed' = True is invalid; expected an integer"),
    ({"mode": "fast"}, "'mode' = 'fast' is invalid; expected one of ('realtime', 'lockstep')"),
    ({"xyz": [1.0, 2.0]}, "'xyz' = [1.0, 2.0] is invalid: 2 elements; expected 3 finite numbers"),
    ({"timeout": math.nan}, "'timeout' = nan is invalid; expected a number"),
])
def test_wrong_values_give_one_clear_error(ros, overrides, needle):
    with pytest.raises(ValueError) as e:
        node, _ = make("t_bad", overrides, specs([]))
        node.destroy_node()
    assert needle in str(e.value)


def test_runtime_set_takes_effect_or_is_rejected_with_a_reason_over_dds(ros):
    from rclpy.parameter_client import AsyncParameterClient

    applied = []
    node, p = make("t_runtime", {}, specs(applied))
    client_node = rclpy.create_node("t_runtime_client")
    try:
        client = AsyncParameterClient(client_node, "t_runtime")
        assert client.wait_for_services(10.0)

        def call(params):
            fut = client.set_parameters(params)
            both = [node, client_node]
            ex = rclpy.executors.SingleThreadedExecutor()
            for n in both:
                ex.add_node(n)
            ex.spin_until_future_complete(fut, timeout_sec=10.0)
            for n in both:
                ex.remove_node(n)
            return fut.result().results[0]

        r = call([Parameter("timeout", value=2)])          # an int for a float: taken, applied
        assert r.successful, r.reason
        assert applied == [2.0] and p["timeout"] == 2.0 and node.get_parameter("timeout").value == 2.0
        r = call([Parameter("timeout", value=100.0)])      # out of range
        assert not r.successful and "out of range" in r.reason and p["timeout"] == 2.0
        r = call([Parameter("rate_hz", value=5.0)])        # fixed at start
        assert not r.successful and "read-only" in r.reason and p["rate_hz"] == 10.0
        assert applied == [2.0]
    finally:
        client_node.destroy_node()
        node.destroy_node()


def test_two_params_groups_on_one_node_set_at_run_time(ros):
    """A node may declare `config` first and the rest after reading it: one set of rclpy callbacks
    serves both (rclpy concatenates what every pre-set callback returns, so two would duplicate
    every parameter and turn an int-for-float set into a type error)."""
    applied = []
    node = rclpy.create_node("t_two_groups")
    try:
        first = Params(node, [Param("config", "", "parameter file")])
        second = Params(node, [Param("timeout", 0.5, "input timeout", lo=0.01, hi=60.0,
                                     on_change=lambda v: applied.append(v))])
        res = node.set_parameters([Parameter("timeout", value=3)])
        assert res[0].successful, res[0].reason
        assert applied == [3.0] and second["timeout"] == 3.0 and first["config"] == ""
        assert node.get_parameter("timeout").type_ == Parameter.Type.DOUBLE
    finally:
        node.destroy_node()


def test_discovery_wait_from_the_environment(monkeypatch):
    from lhd_loading_ros.ros.params import DISCOVERY_WAIT_DEFAULT_S, DISCOVERY_WAIT_ENV, discovery_wait_s

    monkeypatch.delenv(DISCOVERY_WAIT_ENV, raising=False)
    assert discovery_wait_s() == DISCOVERY_WAIT_DEFAULT_S == 3.0
    monkeypatch.setenv(DISCOVERY_WAIT_ENV, "0.5")
    assert discovery_wait_s() == 0.5
    monkeypatch.setenv(DISCOVERY_WAIT_ENV, " ")
    assert discovery_wait_s() == 3.0
    for bad in ("-1", "nan", "soon", "inf"):
        monkeypatch.setenv(DISCOVERY_WAIT_ENV, bad)
        with pytest.raises(ValueError, match="LHD_DISCOVERY_WAIT_S.*expected seconds >= 0"):
            discovery_wait_s()
