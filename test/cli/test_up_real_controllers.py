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
    assert "policy_dir" not in params and extra == ["-r", "/lhd/cmd:=/lhd/cmd/auto"]
    assert sup["controller"] == controller and sup["policy_dir"] == ""     # the record's label


def test_an_actor_and_teleop(tmp_path):
    (module, params, _), sup = controller_node(["--controller", "rlc"], tmp_path)
    assert "controller" not in params and params["policy_dir"].endswith("policies/rlc")
    assert controller_node(["--controller", "teleop"], tmp_path)[0] is None


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
    assert own["lhd_policy"]["ros__parameters"]["teacher_drift_confirm"] == 1
