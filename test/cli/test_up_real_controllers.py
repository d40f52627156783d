"""`lhd up real --controller`: which controller the stack's policy node runs, and the flags that do
not apply to it refused before any node starts (cli/up_real.stack and check_args, no processes)."""
import copy
from pathlib import Path

import pytest
import yaml

from lhd_loading_ros.cli.up_real import check_args, parser, stack

ROOT = Path(__file__).resolve().parents[2]


def controller_node(argv, tmp_path):
    ap = parser()
    args = ap.parse_args(["--port", "/dev/null", *argv])
    check_args(ap, args)
    nodes = {name: (module, params, extra) for name, module, params, extra in stack(args, tmp_path)}
    return nodes.get("controller"), nodes["supervisor"][1]


@pytest.mark.parametrize("controller", ["tampier", "teacher"])
def test_the_baselines_run_in_the_policy_node_without_an_actor(controller, tmp_path):
    (module, params, extra), sup = controller_node(["--controller", controller], tmp_path)
    assert module == "lhd_loading_ros.nodes.policy_node" and params["controller"] == controller
    assert "policy_dir" not in params and extra == [] and params["cmd_topic"] == "cmd/auto"   # to the mux
    assert sup["controller"] == controller and sup["policy_dir"] == ""     # the record's label


def test_an_actor_and_teleop(tmp_path):
    (module, params, _), sup = controller_node(["--controller", "rlc", "--policy", "policies/rlc"], tmp_path)
    assert "controller" not in params and params["policy_dir"].endswith("policies/rlc")
    assert "config" not in params                       # policies/rlc runs on the package's parameter file
    assert controller_node(["--controller", "teleop"], tmp_path)[0] is None


@pytest.mark.parametrize("controller, actor", [("rld", "rld_drift_confirm_margin8"), ("rlc", "rlc_gains")])
def test_the_machine_runs_the_actors_that_pass_the_machine_case_with_their_own_file(controller, actor, tmp_path):
    """Without --policy the real stack runs the machine's actors (actor_file.MACHINE_ACTORS: placed by
    hand, from rest, on a rough pile, `lhd eval --stress machine` 1.000 / 0.983 against the main job's
    0.61 / 0.70, docs/evidence/machine_case/), and every node that reads a parameter file reads the
    actor's own (the nodes refuse an actor under another file's observation scaling). A --config given
    is kept; an actor without its own file runs on the package's."""
    ap = parser()
    args = ap.parse_args(["--port", "/dev/null", "--controller", controller])
    check_args(ap, args)
    nodes = {name: params for name, _, params, _ in stack(args, tmp_path)}
    own = str(ROOT / "policies" / actor / "lhd_params.yaml")
    assert nodes["controller"]["policy_dir"] == str(ROOT / "policies" / actor)
    assert nodes["supervisor"]["policy_dir"] == str(ROOT / "policies" / actor)
    for name in ("bridge", "end_zone", "supervisor", "controller"):
        assert nodes[name]["config"] == own, name
    assert f"--controller {controller}: " in args.actor_note and "the machine's default actor" in args.actor_note
    # the same actor named: its own file, no default note
    args = ap.parse_args(["--port", "/dev/null", "--controller", controller, "--policy", f"policies/{actor}"])
    check_args(ap, args)
    assert Path(args.config) == ROOT / "policies" / actor / "lhd_params.yaml"
    assert "default" not in args.actor_note and "the actor's own" in args.actor_note
    # a --config given wins (and is checked against the actor: the package's file has other scaling)
    args = ap.parse_args(["--port", "/dev/null", "--controller", controller, "--config",
                          str(ROOT / "config" / "lhd_params.yaml")])
    with pytest.raises(SystemExit) as e:
        check_args(ap, args)
    assert e.value.code == 2


def test_flags_that_do_not_apply_are_refused(tmp_path, capsys):
    ap = parser()
    args = ap.parse_args(["--port", "/dev/null", "--controller", "teacher", "--policy", "policies/rld"])
    with pytest.raises(SystemExit) as e:
        check_args(ap, args)
    assert e.value.code == 2
    assert "--policy is the actor's; --controller teacher runs no actor" in capsys.readouterr().err
    # a parameter file whose demonstrations' crowd range is upside down
    cfg = yaml.safe_load((ROOT / "config" / "lhd_params.yaml").read_text())
    bad = copy.deepcopy(cfg)
    bad["training"].update(demo_crowd_min=0.8, demo_crowd_max=0.6)
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(bad))
    args = ap.parse_args(["--port", "/dev/null", "--controller", "teacher", "--config", str(f)])
    with pytest.raises(SystemExit):
        check_args(ap, args)
    assert "relation violated: training.demo_crowd_min <= training.demo_crowd_max" in capsys.readouterr().err


def test_the_machine_parameter_file_confirms_the_teachers_drift():
    """config/real_machine.yaml, which `lhd up real` and `lhd up twin` pass to every node, gives the
    policy node teacher_drift_confirm 6 (the start-up wheel slip; docs/baselines.md), read as rcl
    reads it; the node's own default stays the training's 1 (config/policy_node.yaml)."""
    from lhd_loading_ros.cli.up_real import default_params_file, node_params

    assert node_params(default_params_file(), "/lhd_policy")["teacher_drift_confirm"] == 6
    own = yaml.safe_load((ROOT / "config" / "policy_node.yaml").read_text())
    from lhd_loading_ros.ros.params_file import params_of

    assert params_of(own, "/lhd_policy")["teacher_drift_confirm"] == 1


def test_machine_actor_is_the_launch_files_rule_too(tmp_path, monkeypatch):
    """real_machine.launch.py resolves the actor, the parameter file and the supervisor's slope limits
    with the same function (cli/up_real.machine_actor) over the installed share's policies: the
    machine's actor for rld / rlc without policy_dir, armed on the slopes where it keeps 0.9 of the machine
    case (rld_drift_confirm_margin8 10-35 deg, its card 10-40: the machine case has no 37.5-40 deg piles; rlc_gains 10-35),
    its own file unless config:= or
    $LHD_CONFIG names one; nothing for the baselines."""
    from lhd_loading_ros.cli.up_real import machine_actor

    monkeypatch.delenv("LHD_CONFIG", raising=False)
    share = tmp_path / "policies"
    (share / "rld_drift_confirm_margin8").mkdir(parents=True)
    (share / "rld_drift_confirm_margin8" / "lhd_params.yaml").write_text("# the actor's own\n")
    (share / "rld").mkdir()
    chosen = machine_actor("rld", policies_root=share)
    assert chosen.policy == str(share / "rld_drift_confirm_margin8")
    assert chosen.config == str((share / "rld_drift_confirm_margin8" / "lhd_params.yaml").resolve())
    assert chosen.slope_limits == (10.0, 35.0) and "the machine's default actor" in chosen.note
    assert machine_actor("rlc", policies_root=share).slope_limits == (10.0, 35.0)
    assert machine_actor("rld", str(share / "rld"), policies_root=share)[:3] == (str(share / "rld"), "", None)
    assert machine_actor("rld", "", "/x/mine.yaml", policies_root=share)[:2] == (str(share / "rld_drift_confirm_margin8"), "/x/mine.yaml")
    assert machine_actor("tampier", "", "", policies_root=share) == ("", "", None, "")
    assert machine_actor("teleop", "", "/x/mine.yaml", policies_root=share) == ("", "/x/mine.yaml", None, "")
    # $LHD_CONFIG is an explicit choice, as --config is: every node reads it, the note says so
    monkeypatch.setenv("LHD_CONFIG", "/x/env.yaml")
    chosen = machine_actor("rld", policies_root=share)
    assert chosen.config == "" and "/x/env.yaml ($LHD_CONFIG)" in chosen.note


def test_every_node_that_reads_a_parameter_file_reads_the_same_one(tmp_path, monkeypatch, capsys):
    """The mux and the teleop node read the actuator ranges from the parameter file: they get the
    stack's, as the bridge, the end zone, the supervisor and the controller do (a review: they read the
    package's while the rest read the actor's). The supervisor gets the machine actor's slope limits."""
    monkeypatch.delenv("LHD_CONFIG", raising=False)
    ap = parser()
    args = ap.parse_args(["--port", "/dev/null", "--controller", "rld"])
    check_args(ap, args)
    nodes = {name: params for name, _, params, _ in stack(args, tmp_path)}
    own = str(ROOT / "policies" / "rld_drift_confirm_margin8" / "lhd_params.yaml")
    assert {n for n, p in nodes.items() if p.get("config") == own} == {"bridge", "end_zone", "supervisor", "mux",
                                                                       "teleop", "controller"}
    assert nodes["supervisor"]["slope_limits_deg"] == [10.0, 35.0]
    args = ap.parse_args(["--port", "/dev/null", "--controller", "rld", "--policy", "policies/rld_machine"])
    check_args(ap, args)
    assert "slope_limits_deg" not in {n: p for n, p in ((n, p) for n, _, p, _ in stack(args, tmp_path))}["supervisor"]
    # a --config that does not fit the default actor: the refusal says the default changed and how to go back
    args = ap.parse_args(["--port", "/dev/null", "--controller", "rld", "--config", str(ROOT / "config" / "lhd_params.yaml")])
    capsys.readouterr()
    with pytest.raises(SystemExit):
        check_args(ap, args)
    err = capsys.readouterr().err
    assert "runs " in err and "policies/rld_drift_confirm_margin8 by default (since 2026-12-02 for rld)" in err and "--policy policies/rld" in err
