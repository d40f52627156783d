"""run_node's shutdown deadline: a clean-up that hangs (a review saw a node's destroy stuck inside
rclpy, at 80 % CPU, ignoring SIGTERM, after its launcher died) ends the process SHUTDOWN_DEADLINE_S
after the stop; a clean-up that finishes leaves no alarm behind. Real processes, real rclpy."""
import os
import signal
import subprocess
import sys
import textwrap
import time

from rosutil import readline_past_middleware, unique_domain_id

SCRIPT = textwrap.dedent("""
    import sys, time
    import rclpy
    from lhd_loading_ros.ros.run import run_node

    def make():
        node = rclpy.create_node("run_node_deadline_test")
        print("up", flush=True)
        return node

    def cleanup(node):
        print("cleaning up", flush=True)
        time.sleep(float(sys.argv[1]))

    rc = run_node(make, "deadline_test", before_destroy=cleanup, shutdown_deadline_s=1)
    time.sleep(1.5)                  # an alarm left armed would end the process here
    print(f"returned {rc}", flush=True)
    sys.exit(rc)
""")


def run(cleanup_s: float):
    env = dict(os.environ, ROS_DOMAIN_ID=str(unique_domain_id()), PYTHONUNBUFFERED="1")
    p = subprocess.Popen([sys.executable, "-c", SCRIPT, str(cleanup_s)], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, env=env)
    assert readline_past_middleware(p.stdout).strip() == "up"
    p.send_signal(signal.SIGTERM)
    t0 = time.monotonic()
    try:
        rc = p.wait(30)
    finally:
        p.kill()
    return rc, time.monotonic() - t0, p.stdout.read()


def test_a_hung_clean_up_ends_the_process_at_the_deadline():
    rc, took, out = run(60.0)
    assert rc == -signal.SIGALRM and "cleaning up" in out and "returned" not in out, (rc, out)
    assert took < 5.0, took


def test_a_clean_up_in_time_returns_and_leaves_no_alarm():
    rc, took, out = run(0.1)
    assert rc == 0 and "returned 0" in out, (rc, out)


def test_the_launchers_stop_on_sighup_unless_nohup():
    """A closed terminal (SIGHUP) stops a launcher in order, as SIGTERM does (it used to kill it at
    once, its nodes then all stopping together); under nohup (SIGHUP ignored) it stays ignored."""
    script = textwrap.dedent("""
        import os, signal, sys, threading
        from lhd_loading_ros.cli.launcher import _StopOnSignals
        if sys.argv[1] == "nohup":
            signal.signal(signal.SIGHUP, signal.SIG_IGN)
        else:   # a terminal's default, whatever this test run inherited (a suite run under nohup ignores SIGHUP)
            signal.signal(signal.SIGHUP, signal.SIG_DFL)
        ev = threading.Event()
        with _StopOnSignals(ev):
            os.kill(os.getpid(), signal.SIGHUP)
            print("stop" if ev.wait(2.0) else "running", flush=True)
        print("restored" if signal.getsignal(signal.SIGHUP) in (signal.SIG_DFL, signal.SIG_IGN) else "not", flush=True)
    """)
    for how, expected in (("terminal", "stop\nrestored\n"), ("nohup", "running\nrestored\n")):
        p = subprocess.run([sys.executable, "-c", script, how], capture_output=True, text=True, timeout=60)
        assert p.returncode == 0 and p.stdout == expected, (how, p.stdout, p.stderr)
