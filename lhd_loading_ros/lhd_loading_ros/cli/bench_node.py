"""`lhd bench node`: the policy node's cycle at 10 Hz against the sim node (realtime, a
separate process on real DDS). Measured inside the node: latency = observation build to
command publish; jitter = |timer period - 100 ms|. At least 1,000 cycles (100 s).

The policy node commands only while /lhd/episode says an attempt is running; here the sim node
is that publisher (state running from the moment it is up, new episodes at once: reset_delay 0),
so the bench publishes no status of its own: a second publisher of /lhd/episode would contradict
the sim node's end-of-episode states."""
from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path


def bench_node(cycles: int = 1000, policy: str | None = None) -> dict:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from lhd_loading_ros.cli.launcher import Child
    from lhd_loading_ros.nodes.policy_node import PolicyNode

    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
    with tempfile.TemporaryDirectory(prefix="lhd_bench_node_") as log_dir:
        sim = Child("sim_node", "lhd_sim_node.sim_node", {"mode": "realtime", "reset_delay": 0.0}, Path(log_dir),
                    quiet=True)
        rclpy.init()
        overrides = [Parameter("policy_dir", value=policy)] if policy else []
        node = PolicyNode(parameter_overrides=overrides)
        ex = SingleThreadedExecutor()
        ex.add_node(node)
        try:
            t_end = time.monotonic() + 60.0
            while not node.latencies_ms and time.monotonic() < t_end:     # the sim node is up and publishing
                ex.spin_once(timeout_sec=0.05)
            if not node.latencies_ms:
                raise RuntimeError("the policy node produced no command from the sim node's topics within 60 s; "
                                   f"sim node log:\n{sim.log_path.read_text()[-2000:]}")
            node.latencies_ms.clear()
            node.periods_ms.clear()
            while len(node.latencies_ms) < cycles:
                ex.spin_once(timeout_sec=0.2)
            s = node.stats()
        finally:
            ex.remove_node(node)
            node.destroy_node()
            rclpy.shutdown()
            sim.stop()
    return {"latency_p50_ms": round(s["latency_p50_ms"], 4), "latency_p99_ms": round(s["latency_p99_ms"], 4),
            "jitter_p99_ms": round(s["jitter_p99_ms"], 3), "cycles": len(node.latencies_ms),
            "rate_hz": node.rate_hz}
