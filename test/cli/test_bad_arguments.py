"""Bad command-line values are refused at once, naming the flag and what is expected, with exit
status 2 and no traceback (found by a reviewer trying cases no test named, 2026-11-28): negative
seeds and counts, zero steps, non-finite time limits, the heuristic's flags given to an actor's
evaluation, --randomize with --stress, and a topic prefix that is no ROS name. Each case runs the
real command in a process."""
PARALLEL_SAFE = True   # command-line runs that only parse and exit (test/conftest.py)

import subprocess
import sys

import pytest

LHD = [sys.executable, "-m", "lhd_loading_ros.cli.main"]


@pytest.mark.parametrize("args, needle", [
    (["train", "--variant", "rld", "--seed", "-1"], "argument --seed: expected an integer >= 0, got -1"),
    (["eval", "--policy", "policies/rld", "--seed", "-5"], "argument --seed: expected an integer >= 0, got -5"),
    (["eval", "--controller", "tampier", "--seed", "-1"], "argument --seed: expected an integer >= 0, got -1"),
    (["experiment", "paper", "--seed", "x"], "argument --seed: expected an integer, got 'x'"),
    (["demo", "--seed", "-1"], "argument --seed: expected an integer >= 0, got -1"),
    (["bench", "sim", "--steps", "0"], "argument --steps: expected an integer >= 1, got 0"),
    (["bench", "sim", "--steps", "-5"], "argument --steps: expected an integer >= 1, got -5"),
    (["echo", "/lhd/cmd", "--count", "-1"], "argument --count: expected an integer >= 0, got -1"),
    (["attempt", "mass", "23.4", "--attempt", "-1"], "argument --attempt: expected an integer >= 1, got -1"),
    (["attempt", "mass", "23.4", "--attempt", "0"], "argument --attempt: expected an integer >= 1, got 0"),
    (["eval", "--controller", "tampier", "--time-limit", "inf", "--episodes", "1"],
     "tampier eval: --time-limit inf: expected seconds >= 0"),
    (["eval", "--controller", "tampier", "--time-limit", "nan", "--episodes", "1"],
     "tampier eval: --time-limit nan: expected seconds >= 0"),
    # each bad argument named alone, an empty slope between commas too (a review)
    (["eval", "--controller", "tampier", "--slopes", "2O", "--episodes", "1"],
     "tampier eval: --slopes '2O': expected comma-separated degrees"),
    (["eval", "--controller", "tampier", "--slopes", "20,,25", "--episodes", "1"],
     "tampier eval: --slopes '20,,25': expected comma-separated degrees"),
    (["eval", "--policy", "policies/rld", "--episodes", "2", "--slopes", "20"],
     "--slopes applies to --controller tampier only"),
    (["eval", "--policy", "policies/rld", "--material", "homogeneous", "--time-limit", "5"],
     "--material, --time-limit apply to --controller tampier only"),
    (["eval", "--policy", "policies/rld", "--stress", "dense", "--randomize"],
     "--randomize and --stress are alternatives"),
    (["eval", "--controller", "tampier", "--zones", "end-zone-node"],
     "--randomize, --stress, --deploy-filter and --zones apply to --controller actor only"),
    # a review (2026-12-01): the actor's folder was ignored without a word, and a file for a folder said "does not exist"
    (["eval", "--controller", "tampier", "--policy", "policies/rld"],
     "--policy policies/rld with --controller tampier: the heuristic runs no actor"),
    (["report", "policies", "--zones", "end-zone-node"], "--zones and --zones-density apply to --held-out only"),
    (["eval", "--policy", "policies/rld", "--zones-density", "1550"],
     "--zones-density 1550 is the end-zone node's density: it needs --zones end-zone-node"),
    (["eval", "--policy", "policies/rld", "--zones", "end-zone-node", "--zones-density", "1.6"],
     "--zones-density 1.6: bulk density 1.6 kg/m^3 outside [500, 6000] kg/m^3"),
    (["experiment", "paper", "--episodes", "1", "--zones-density", "1550"],
     "--zones-density 1550 is the end-zone node's density: it needs --zones end-zone-node"),
    (["eval", "--policy", "policies/rld", "--zones", "lidar"],
     "argument --zones: invalid choice: 'lidar' (choose from 'pile', 'end-zone-node')"),
    # a misspelled twin parameter: ROS would drop an undeclared -p override silently (a plane pile
    # where a rough one was asked for, found by a reviewer on 2026-11-28)
    (["up", "sim", "--slope", "nan"], "--slope nan: not a finite number; expected slopes in degrees, e.g. 20"),
    # `lhd experiment paper` (a review: a raw multiprocessing message, an internal option name)
    (["experiment", "paper", "--episodes", "1", "--jobs", "-1"], "--jobs must be >= 0 (0: one per core), got -1"),
    (["experiment", "paper", "--episodes", "1", "--slopes", "10,20"],
     "--slopes: 10 deg outside the piles of the parameter file (15-30 deg"),
    # `lhd up real`: a port that does not exist, an attempt timeout the supervisor would refuse
    # (it used to start nine nodes, then the bridge retried for ever or the supervisor exited 2)
    (["up", "real", "--port", "/dev/ttyNOPE"], "--port '/dev/ttyNOPE' is no serial device (missing, empty or a "
                                                "directory): expected the Due's serial device, e.g. /dev/ttyACM0"),
    # an empty port is the current directory to pathlib, which exists: nine nodes started (a review, 2026-11-29)
    (["up", "real", "--port", ""], "--port '' is no serial device (missing, empty or a directory)"),
    (["up", "real", "--port", "/dev"], "--port '/dev' is no serial device"),
    # namespaces and timeouts of the one-shot commands (a review: a traceback, and a timeout of -1 accepted)
    (["estop", "on", "--namespace", "x y"], "'x y' is no ROS namespace"),
    (["arm", "--timeout", "-1"], "--timeout: expected a number of seconds > 0, got -1"),
    (["attempt", "mass", "20", "--namespace", "/"], "expected the machine's topic prefix, e.g. /lhd"),
    (["up", "real", "--port", "/dev/null", "--attempt-timeout", "nan"], "--attempt-timeout nan: expected seconds in "
                                                                        "[0.1, 600]"),
    (["up", "real", "--port", "/dev/null", "--attempt-timeout", "1000"], "--attempt-timeout 1000: expected seconds in "
                                                                         "[0.1, 600]"),
    (["up", "twin", "--twin-param", "pile_releif_sd=0.03"],
     "the twin node has no parameter 'pile_releif_sd'; did you mean 'pile_relief_sd'?"),
])
def test_a_bad_value_is_one_line_and_exit_2(args, needle):
    p = subprocess.run(LHD + args, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, (p.returncode, p.stdout[-500:], p.stderr[-1500:])
    assert needle in p.stderr, p.stderr[-1500:]
    assert "Traceback" not in p.stderr and p.stdout == ""


def test_a_refused_experiment_leaves_no_folder_and_a_path_that_cannot_be_written_is_one_line(tmp_path):
    """A refused `lhd experiment paper` used to leave its empty --out folder; an --out under a file,
    or `lhd mjcf --out` into a folder that does not exist, ended with a traceback (a review)."""
    out = tmp_path / "refused"
    p = subprocess.run(LHD + ["experiment", "paper", "--episodes", "0", "--out", str(out)], capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 2 and "episodes must be >= 1" in p.stderr and not out.exists(), p.stderr
    (tmp_path / "a_file").write_text("x")
    for args, needle in ((["experiment", "paper", "--episodes", "1", "--out", str(tmp_path / "a_file" / "x")],
                          "lhd experiment paper: [Errno 20] Not a directory"),
                         (["mjcf", "--out", str(tmp_path / "no_such_dir" / "m.xml")],
                          "lhd mjcf: [Errno 2] No such file or directory")):
        p = subprocess.run(LHD + args, capture_output=True, text=True, timeout=120)
        assert p.returncode == 1 and p.stderr.startswith(needle) and "Traceback" not in p.stderr, p.stderr


@pytest.mark.parametrize("module", ["lhd_loading_ros.nodes.cmd_mux_node", "lhd_sim_node.sim_node"])
@pytest.mark.parametrize("prefix, why", [("bad topic!", "must not contain characters other than alphanumerics"),
                                         ("/lhd/9x", "must not start with a number")])
def test_a_prefix_that_is_no_ros_name_ends_the_node_with_one_line(module, prefix, why):
    p = subprocess.run([sys.executable, "-m", module, "--ros-args", "-p", f"namespace_prefix:={prefix}"],
                       capture_output=True, text=True, timeout=120)
    out = p.stdout + p.stderr
    assert p.returncode == 2, out[-1500:]
    assert f"parameter 'namespace_prefix' = {prefix!r} is invalid: expected a ROS topic prefix such as /lhd" in out
    assert why in out and "Traceback" not in out


@pytest.mark.parametrize("group, needle", [
    ("up", "lhd up sim"), ("attempt", "lhd attempt mass KG"), ("validate", "lhd validate physics"),
])
def test_help_of_a_command_group_shows_its_subcommands_and_exits_0(group, needle):
    """`lhd up --help` (and `attempt`, `validate`) print their subcommands and exit 0, as every other
    command's --help does (a review: they exited 2 with the one-line usage error)."""
    for flag in ("--help", "-h"):
        r = subprocess.run(LHD + [group, flag], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0 and needle in r.stdout and "Traceback" not in r.stderr, (r.stdout, r.stderr)
    r = subprocess.run(LHD + [group], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and needle in r.stderr


def edited_config(path, *edits):
    """The shipped parameter file with each (old, new) text replaced (each must occur), written to path."""
    from pathlib import Path
    text = (Path(__file__).resolve().parents[2] / "config" / "lhd_params.yaml").read_text()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    path.write_text(text)
    return path


def test_a_file_whose_piles_the_attack_cannot_enter_is_one_line(tmp_path):
    """A legal but extreme file (a 50 kPa cohesive pile: the attack drive cannot bury the lip 0.1 m)
    ends an in-process command with one line naming what failed, as the sim node does, not with the
    simulator's traceback (a review)."""
    f = edited_config(tmp_path / "cohesive.yaml", ("  cohesion_min: 0.0 ", "  cohesion_min: 50000.0 "),
                      ("  cohesion_max: 0.0\n", "  cohesion_max: 50000.0\n"))
    r = subprocess.run(LHD + ["eval", "--controller", "tampier", "--config", str(f), "--episodes", "1", "--slopes",
                              "20"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith("lhd eval: the attack drive could not bury the bucket in a pile of this parameter "
                               "file: the bucket did not reach d_init"), r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_validate_physics_names_a_file_whose_piles_miss_its_cases(tmp_path):
    """`lhd validate physics` works its references at 15-30 deg piles: a file of 10-14 deg piles is
    refused in one line naming both ranges, exit 2 (a review: a traceback from the environment)."""
    f = edited_config(tmp_path / "shallow.yaml", ("    alpha_min_deg: 15.0", "    alpha_min_deg: 10.0"),
                      ("    alpha_max_deg: 30.0", "    alpha_max_deg: 14.0"))
    r = subprocess.run(LHD + ["validate", "physics", "--quick", "--config", str(f)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert "its cases are piles of 15-30 deg" in r.stderr and "has piles of 10-14 deg" in r.stderr


@pytest.mark.parametrize("module, param", [("lhd_loading_ros.nodes.teleop_node", "joy_topic:=bad topic"),
                                           ("lhd_loading_ros.nodes.lidar_slope_node", "scan_topic:=/scan/9x"),
                                           ("lhd_loading_ros.nodes.teleop_node", "use_sim_time:=1")])
def test_a_topic_parameter_that_is_no_ros_name_or_a_mistyped_bool_is_one_line(module, param):
    """rclpy refuses these while the node is made (InvalidTopicNameException, InvalidParameterTypeException):
    a 25-line traceback and exit 1 until a review (2026-11-29, twelfth session); now one line (ros/run.py)."""
    p = subprocess.run([sys.executable, "-m", module, "--ros-args", "-p", param], capture_output=True, text=True,
                       timeout=120)
    out = p.stdout + p.stderr
    assert p.returncode == 2 and "Traceback" not in out, out[-1500:]
    lines = [ln for ln in out.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    want = "expecting type 'BOOL'" if "use_sim_time" in param else "expected a ROS name"
    assert want in lines[0] and param.split(":=")[1] in lines[0]


def test_a_file_given_as_the_policy_folder_is_named_as_a_file():
    """A policy that cannot be loaded is an error of the run (exit 1, as a missing folder), not of the
    arguments; a file given for the folder said "does not exist" (a review, 2026-12-01)."""
    p = subprocess.run([*LHD, "eval", "--policy", "README.md", "--episodes", "1"], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 1 and "Traceback" not in p.stderr, (p.returncode, p.stderr[-1500:])
    assert "policy directory README.md is a file, not a directory; expected a directory with actor.npz" in p.stderr
