"""`lhd bench bridge`: parser throughput and serial-frame-to-ROS-publish latency.

frames_per_s: sensor frames parsed per second by FrameParser from one long byte stream.
latency_p50_ms / latency_p99_ms: from the moment the device emulator stamps a sensor frame
(just before writing it to the pseudo-terminal) to the moment the bridge node has published
/lhd/joint_states and the drift topics for it, measured with the same monotonic clock (emulator
and node in one process, the node running its normal serial thread and executor).
"""
from __future__ import annotations

import os
import tempfile
import threading
import time

import numpy as np

from .protocol import FrameParser, SensorFrame, encode


def parser_throughput(n: int = 20000) -> float:
    frames = [SensorFrame(i * 10000, -0.3, 0.5, -0.19, 0.2, 2.7, 2.6, 2.5, 3.0, 3.0, 5.0, 1, 1, 1) for i in range(64)]
    wire = b"".join(encode(frames[i % 64], i) for i in range(n))
    best = float("inf")
    for _ in range(3):
        p = FrameParser()
        t0 = time.perf_counter()
        for k in range(0, len(wire), 4096):  # serial reads arrive in chunks
            p.feed(wire[k:k + 4096])
        best = min(best, time.perf_counter() - t0)
        assert p.frames == n
    return n / best


def publish_latency(seconds: float = 4.0, rate: float = 500.0) -> np.ndarray:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from .bridge_node import BridgeNode
    from .fake_due import FakeDue

    os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    link = os.path.join(tempfile.mkdtemp(prefix="lhd_bench_"), "due")
    dev = FakeDue(link=link, rate=rate)
    dev.plug()
    rclpy.init()
    lat = []
    try:
        node = BridgeNode(parameter_overrides=[Parameter("port", value=link)])
        t0 = [None]

        def hook(f: SensorFrame):
            if t0[0] is not None:
                lat.append(time.monotonic() - (t0[0] + f.device_time_us * 1e-6))

        node.latency_hook = hook
        ex = SingleThreadedExecutor()
        ex.add_node(node)
        stop = threading.Event()
        spin = threading.Thread(target=lambda: [ex.spin_once(timeout_sec=0.05) for _ in iter(stop.is_set, True)],
                                daemon=True)
        spin.start()
        time.sleep(1.0)  # link up
        # the emulator stamps frames with time since its loop started
        t0[0] = time.monotonic()
        dev_start = dev.start
        dev._run_t0 = t0[0]
        dev_start()
        time.sleep(seconds)
        stop.set()
        spin.join(timeout=2.0)
        node.shutdown()
        node.destroy_node()
    finally:
        dev.stop()
        rclpy.shutdown()
    return np.array(lat[10:]) * 1e3


def bench_bridge(seconds: float = 4.0) -> dict:
    fps = parser_throughput()
    lat = publish_latency(seconds)
    return {
        "frames_per_s": round(fps, 1),
        "latency_p50_ms": round(float(np.percentile(lat, 50)), 3),
        "latency_p99_ms": round(float(np.percentile(lat, 99)), 3),
        "latency_samples": int(lat.size),
    }
