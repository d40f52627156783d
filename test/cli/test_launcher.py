"""`lhd up sim` and `lhd demo` start real node processes; they must finish the asked episodes,
stop cleanly on Ctrl-C, and leave no process behind. `lhd echo` prints a live topic."""
import json
import os
import signal
import subprocess
import sys
import time

from rosutil import unique_domain_id


def env_with_domain():
    return dict(os.environ, ROS_DOMAIN_ID=str(unique_domain_id()), PYTHONUNBUFFERED="1")


def leftovers(marker: str) -> list[str]:
    out = subprocess.run(["pgrep", "-af", marker], capture_output=True, text=True).stdout
    return [line for line in out.splitlines() if "pgrep" not in line]


def test_up_sim_runs_episodes_and_leaves_nothing_behind():
    marker = "seed:=424242"
    p = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "up", "sim", "--mode", "lockstep", "--slope", "25",
                        "--episodes", "2", "--seed", "424242", "--material", "homogeneous", "--json"],
                       capture_output=True, text=True, timeout=240, env=env_with_domain())
    assert p.returncode == 0, p.stderr[-3000:]
    res = json.loads(p.stdout)
    assert len(res["episodes"]) == 2
    assert all(e["alpha_deg"] == 25.0 and e["material"] == "homogeneous" for e in res["episodes"])
    assert "25" in res["rows"]
    time.sleep(0.5)
    assert leftovers(marker) == []


def test_up_sim_stops_cleanly_on_ctrl_c():
    marker = "seed:=434343"
    p = subprocess.Popen([sys.executable, "-m", "lhd_loading_ros.cli.main", "up", "sim", "--seed", "434343"],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env_with_domain(),
                         start_new_session=True)
    try:
        t_end = time.monotonic() + 120
        lines = []
        while time.monotonic() < t_end:      # wait for the first finished attempt: both nodes are working
            line = p.stdout.readline()
            lines.append(line)
            if line.startswith("episode"):
                break
        assert any(line.startswith("episode") for line in lines), "".join(lines)
        assert len(leftovers(marker)) >= 1
        os.killpg(p.pid, signal.SIGINT)
        rc = p.wait(60)
        rest = p.stdout.read()
        assert rc == 0, rest
        assert "interrupted: nodes stopped" in rest
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    time.sleep(0.5)
    assert leftovers(marker) == []


def test_echo_prints_a_topic_as_yaml():
    env = env_with_domain()
    sim = subprocess.Popen([sys.executable, "-m", "lhd_sim_node.sim_node", "--ros-args", "-p", "slope_deg:=20.0",
                            "-p", "mode:=lockstep"], stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, env=env,
                           start_new_session=True)
    try:
        p = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "echo", "/lhd/pile/slope", "--count", "1",
                            "--wait", "60"], capture_output=True, text=True, timeout=120, env=env)
        assert p.returncode == 0, p.stderr
        assert p.stdout.startswith("data: 0.349") and "---" in p.stdout
        bad = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "echo", "/lhd/nothing", "--wait", "1"],
                             capture_output=True, text=True, timeout=60, env=env)
        assert bad.returncode == 1 and "not found" in bad.stderr
    finally:
        os.killpg(sim.pid, signal.SIGINT)
        sim.wait(20)


def test_up_sim_refuses_a_domain_where_a_simulator_already_runs():
    env = env_with_domain()
    sim = subprocess.Popen([sys.executable, "-m", "lhd_sim_node.sim_node"], stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True, start_new_session=True,
                           env=dict(env, RCUTILS_LOGGING_BUFFERED_STREAM="0"))
    try:
        assert "sim node up" in sim.stdout.readline()    # publishing from here on
        seen = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "echo", "/lhd/joint_states", "--count",
                               "1", "--wait", "30"], capture_output=True, text=True, timeout=60, env=env)
        assert seen.returncode == 0, seen.stderr                # another process sees it on the graph
        p = subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.main", "up", "sim", "--episodes", "1",
                            "--seed", "454545"], capture_output=True, text=True, timeout=120, env=env)
        assert p.returncode == 1
        assert "already has publishers" in p.stderr and "/lhd/joint_states" in p.stderr
        assert leftovers("seed:=454545") == []
    finally:
        os.killpg(sim.pid, signal.SIGINT)
        sim.wait(20)
