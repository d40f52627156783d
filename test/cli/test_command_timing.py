"""The controller's rate against the command mux's timeout of its source, checked by `lhd up
real` / `lhd up twin` before anything starts. The mux drops a gated source silent for its timeout
(0.3 s, config/cmd_mux.yaml) and keeps it cut until the attempt ends, so a controller publishing
every 0.25 s (4 Hz) or slower lost every attempt (lost_input), and one barely faster lost those
with one late command. The rule: at least 2 commands per timeout, rate_hz >= 2 / 0.3 = 6.67 Hz."""

import pytest

from lhd_loading_ros.cli.up_real import check_args, command_timing_problem, default_params_file, node_params, parser


def params(tmp_path, text, name="p.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_the_shipped_parameters_pass():
    shipped = default_params_file()
    assert shipped is not None and command_timing_problem(shipped, None) is None     # 10 Hz against 0.3 s
    assert command_timing_problem(None, None) is None


@pytest.mark.parametrize("rate, refused", [(4.0, True), (6.6, True), (6.67, False), (10.0, False)])
def test_the_boundary_is_two_commands_per_timeout(tmp_path, rate, refused):
    # 2 / rate against 0.3 s, by hand: 6.6 Hz -> 0.303 s > 0.3; 6.67 Hz -> 0.29985 s <= 0.3
    p = params(tmp_path, f"lhd_policy:\n  ros__parameters:\n    rate_hz: {rate}\n")
    msg = command_timing_problem(p, None)
    assert (msg is not None) == refused, msg
    if refused:
        assert f"rate {rate:g} Hz (lhd_policy's rate_hz in {p})" in msg and "'auto' after 0.3 s" in msg
        assert "lost_input" in msg and "Expected rate_hz >= 6.67" in msg


def test_the_mux_file_named_in_the_parameters_is_the_one_judged(tmp_path):
    mux = params(tmp_path, "sources:\n  - {name: auto, topic: cmd/auto, priority: 10, timeout: 1.0, gated: true}\n",
                 "mux.yaml")
    p = params(tmp_path, f"lhd_policy:\n  ros__parameters:\n    rate_hz: 4.0\n"
                         f"lhd_cmd_mux:\n  ros__parameters:\n    sources_file: {mux}\n")
    assert command_timing_problem(p, None) is None              # 2 x 0.25 s <= 1 s
    # a wildcard section counts, the node's own section over it (as rcl reads the file)
    p2 = params(tmp_path, "/**:\n  ros__parameters:\n    rate_hz: 2.0\nlhd_policy:\n  ros__parameters:\n"
                          "    rate_hz: 10.0\n", "p2.yaml")
    assert node_params(p2, "lhd_policy")["rate_hz"] == 10.0 and command_timing_problem(p2, None) is None
    p3 = params(tmp_path, "/**:\n  ros__parameters:\n    rate_hz: 2.0\n", "p3.yaml")
    assert "rate 2 Hz" in command_timing_problem(p3, None)


@pytest.mark.parametrize("controller, refused", [("rld", True), ("tampier", True), ("teleop", False)])
def test_lhd_up_real_refuses_before_anything_starts(tmp_path, capsys, controller, refused):
    p = params(tmp_path, "lhd_policy:\n  ros__parameters:\n    rate_hz: 3.0\n")
    ap = parser()
    args = ap.parse_args(["--port", "/dev/null", "--controller", controller, "--params-file", str(p)])
    if refused:
        with pytest.raises(SystemExit) as exc:
            check_args(ap, args)
        assert exc.value.code == 2 and "every attempt would end as lost_input" in capsys.readouterr().err
    else:
        check_args(ap, args)                  # the gamepad drives: no controller, nothing to judge


def test_lhd_up_twin_refuses_it_too(tmp_path, capsys):
    from lhd_loading_ros.cli.up_twin import main

    p = params(tmp_path, "lhd_policy:\n  ros__parameters:\n    rate_hz: 3.0\n")
    with pytest.raises(SystemExit) as exc:
        main(["--params-file", str(p)])
    assert exc.value.code == 2 and "every attempt would end as lost_input" in capsys.readouterr().err


@pytest.mark.parametrize("text, rate", [
    # rcl applies every section whose key matches the node, in file order, the later over the
    # earlier (checked against rclpy's own overrides for /lhd_policy in a review, 2026-11-28)
    ("lhd_policy:\n  ros__parameters:\n    rate_hz: 3.0\n/**:\n  ros__parameters:\n    rate_hz: 10.0\n", 10.0),
    ("/lhd_policy:\n  ros__parameters:\n    rate_hz: 10.0\nlhd_policy:\n  ros__parameters:\n    rate_hz: 3.0\n", 3.0),
    ("/**:\n  lhd_policy:\n    ros__parameters:\n      rate_hz: 3.0\n", 3.0),          # nested: /**/lhd_policy
    ("/**/lhd_policy:\n  ros__parameters:\n    rate_hz: 3.0\n", 3.0),
    ("/lhd/lhd_policy:\n  ros__parameters:\n    rate_hz: 3.0\n", None),              # another namespace's node
    ("/*:\n  ros__parameters:\n    rate_hz: 3.0\n", 3.0),
])
def test_sections_apply_as_rcl_applies_them(tmp_path, text, rate):
    p = params(tmp_path, text)
    assert node_params(p, "/lhd_policy").get("rate_hz") == rate
    assert (command_timing_problem(p, None) is not None) == (rate == 3.0)


def test_a_rate_from_the_config_names_the_config(tmp_path):
    import yaml

    from lhd_loading_ros.task.config import load_config

    cfg = load_config(None)
    cfg["paper"]["control"]["frequency_hz"] = 4.0
    cfg["sim"]["timestep"] = 0.005          # whole physics steps in 0.25 s (50; the FEE every 5 of them)
    c = tmp_path / "lhd_params_4hz.yaml"
    c.write_text(yaml.safe_dump(cfg))
    msg = command_timing_problem(default_params_file(), str(c))
    assert msg is not None and f"rate 4 Hz (paper.control.frequency_hz of {c})" in msg


def test_the_pile_frame_must_be_named_alike_in_every_node(tmp_path, capsys):
    """A pile frame renamed in the LiDAR node's section only: the end-zone node would refuse every
    slope (another frame than its pile_frame_id) and the machine would have no zones."""
    from lhd_loading_ros.cli.up_real import pile_frame_problem

    assert pile_frame_problem(default_params_file()) is None and pile_frame_problem(None) is None
    p = params(tmp_path, "lidar_slope_node:\n  ros__parameters:\n    frame_id: drawpoint_3\n")
    msg = pile_frame_problem(p)
    assert "lidar_slope_node.frame_id = 'drawpoint_3'" in msg and "end_zone_node.pile_frame_id = 'pile'" in msg
    ap = parser()
    with pytest.raises(SystemExit) as exc:
        check_args(ap, ap.parse_args(["--port", "/dev/null", "--controller", "teleop", "--params-file", str(p)]))
    assert exc.value.code == 2 and "expected one name for the pile frame" in capsys.readouterr().err
    # renamed everywhere (a wildcard section): one frame, accepted
    p2 = params(tmp_path, "/**:\n  ros__parameters:\n    frame_id: drawpoint_3\n    pile_frame_id: /drawpoint_3\n",
                "p2.yaml")
    assert pile_frame_problem(p2) is None
