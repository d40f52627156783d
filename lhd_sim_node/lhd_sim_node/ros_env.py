"""Gymnasium environment ``LhdLoadingRos-v0``: the loading task driven through a running sim node.

The learner and the simulator are separate processes (possibly on separate machines of one ROS
domain) that talk only through the sim node's interfaces:

  out  <prefix>/cmd                  std_msgs/Float64MultiArray [u_wheels, u_boom, u_bucket] rad/s: the
                                     actor's action through the variant's filter and the actuator
                                     mapping (task/actions.py), exactly as the policy node sends it
  back <prefix>/rl/transition        the stamped result of that control period: observation, reward,
                                     end flags (task/transition.py)
       <prefix>/episode              the episode's status; at its end the result (outcome, mass,
                                     drift, final pitch) that info["episode_result"] carries
  reset  the sim node's parameters next_seed / slope_deg / material (rcl_interfaces SetParameters),
         then its ~/reset service (std_srvs/Trigger)

The sim node must run in lockstep mode (`-p mode:=lockstep`): one control period per command,
so the episode is the same whatever the network's delays. The environment takes the node's
episodes over (auto_reset off) and checks that both sides read the same parameter file (the
config hash in /episode): a learner must not train on a simulator it does not describe.

With the same seed it gives the same transitions as the in-process LhdLoading-v0 (the sim node
steps that very environment; the observation and reward are carried as float64), so an actor
trained through ROS is the same kind of actor; test/sim/test_ros_env.py compares three episodes.

A sim node per namespace: `namespace=None` is the un-namespaced node (topics /lhd/..., node
/lhd_sim); `namespace="/sim0"` the node started with `-r __ns:=/sim0` (topics /sim0/..., node
/sim0/lhd_sim), as `lhd up sim --count N` starts them. SimNodePool steps several at once (one
learner, several simulators: `lhd train --env ros --namespaces /sim0,/sim1`).

Errors are TimeoutError / RuntimeError with what was expected and how to start a sim node.
"""
from __future__ import annotations

import json
import math
import os
import time
from typing import Any

import gymnasium as gym
import numpy as np

from lhd_loading_ros.task import transition as tr
from lhd_loading_ros.task.actions import apply_variant_filter, to_actuator, validate_action
from lhd_loading_ros.task.config import config_hash, load_config, task_hash
from lhd_loading_ros.task.metrics import result_from_status
from lhd_loading_ros.task.observation import OBS_HIGH, OBS_LOW
from lhd_loading_ros.task.params import TaskParams

from .env import VARIANTS

DEFAULT_TIMEOUT_S = 10.0
NODE_NAME = "lhd_sim"


def start_hint(namespace: str | None) -> str:
    ns = f" -r __ns:={namespace}" if namespace else ""
    return (f"start one with `ros2 run lhd_sim_node sim_node --ros-args -p mode:=lockstep{ns}` "
            f"(or `lhd up sim --count N`; add -p config:=FILE / --config FILE for another parameter file) on the "
            f"same ROS_DOMAIN_ID "
            f"(here {os.environ.get('ROS_DOMAIN_ID', '0')})")


def names(namespace: str | None) -> tuple[str, str]:
    """(topic prefix, fully qualified sim node name) of the sim node in `namespace`."""
    if namespace is None or namespace.strip("/") == "":
        return "/lhd", f"/{NODE_NAME}"
    ns = "/" + namespace.strip("/")
    if any(not (c.isalnum() or c in "_/") for c in ns) or "//" in ns or ns[1].isdigit():
        raise ValueError(f"namespace {namespace!r} is not a ROS namespace; expected e.g. /sim0")
    return ns, f"{ns}/{NODE_NAME}"


UNKNOWN_NODE_NAME = "_NODE_NAME_UNKNOWN_"   # rmw's node name for an endpoint whose node is not yet known


class _SimNodeLink:
    """One lockstep sim node seen from the learner's node."""

    def __init__(self, pool: "SimNodePool", namespace: str | None):
        from diagnostic_msgs.msg import DiagnosticStatus
        from rclpy.parameter_client import AsyncParameterClient
        from std_msgs.msg import Float64MultiArray
        from std_srvs.srv import Trigger

        from lhd_loading_ros.ros.qos import COMMAND_QOS, MEASUREMENT_QOS, STATUS_QOS

        self.namespace = namespace
        self.label = namespace or "/lhd"
        self.prefix, self.fqn = names(namespace)
        node = pool.node
        self._msg = Float64MultiArray
        self.pub = node.create_publisher(Float64MultiArray, f"{self.prefix}/cmd", COMMAND_QOS)
        node.create_subscription(Float64MultiArray, f"{self.prefix}/rl/transition", self._on_transition, MEASUREMENT_QOS)
        node.create_subscription(DiagnosticStatus, f"{self.prefix}/episode", self._on_status, STATUS_QOS)
        self.reset_client = node.create_client(Trigger, f"{self.fqn}/reset")
        self.publishers_client = node.create_client(Trigger, f"{self.fqn}/cmd_publishers")
        self._trigger = Trigger
        self.params = AsyncParameterClient(node, self.fqn)
        self.transitions: dict[tuple[int, int], tr.Transition] = {}
        self.statuses: dict[tuple[int, int], dict] = {}
        self.bad_messages = 0
        self.set_values: dict[str, Any] = {}     # parameters this learner set on the node
        self.last_error = ""
        self.episode = -1           # the sim node's episode we drive
        self.steps = 0
        self.seed = None
        self.done = True

    # messages -------------------------------------------------------------------------------
    def _on_transition(self, msg) -> None:
        try:
            t = tr.decode(msg.data)
        except ValueError as exc:
            self.bad_messages += 1
            self.last_error = str(exc)
            return
        self.transitions[(t.episode, t.step)] = t
        if len(self.transitions) > 64:
            for k in sorted(self.transitions)[:-32]:
                del self.transitions[k]

    def _on_status(self, msg) -> None:
        kv = {v.key: v.value for v in msg.values}
        try:
            key = (int(kv["episode"]), int(kv["step"]))
        except (KeyError, ValueError):
            return
        self.statuses[key] = kv
        if len(self.statuses) > 64:
            for k in sorted(self.statuses)[:-32]:
                del self.statuses[k]

    def latest_status(self) -> dict | None:
        return self.statuses[max(self.statuses)] if self.statuses else None


class SimNodePool:
    """One learner node driving one or more lockstep sim nodes (one per namespace) in step."""

    def __init__(self, namespaces: list[str | None], variant: str = "rld", config=None,
                 timeout: float = DEFAULT_TIMEOUT_S, deploy_filter: bool = False):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        if variant not in VARIANTS:
            raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
        if not namespaces:
            raise ValueError("no sim node namespace given; expected e.g. ['/sim0', '/sim1'] or [None]")
        labels = [names(n)[0] for n in namespaces]
        if len(set(labels)) != len(labels):
            raise ValueError(f"namespaces {namespaces} name one sim node twice")
        if not (math.isfinite(timeout) and timeout > 0):
            raise ValueError(f"timeout must be > 0 s, got {timeout}")
        self.cfg = config if isinstance(config, dict) else load_config(config)
        self.p = TaskParams.from_config(self.cfg)
        self.hash = config_hash(self.cfg)
        self.task_hash = task_hash(self.cfg)
        self.variant, self.deploy_filter, self.timeout = variant, deploy_filter, float(timeout)
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self._closed = False
        try:
            self.node = rclpy.create_node(f"lhd_ros_env_{os.getpid()}_{id(self) % 100000}", context=self.context)
            self.executor = SingleThreadedExecutor(context=self.context)
            self.executor.add_node(self.node)
            self.links = [_SimNodeLink(self, n) for n in namespaces]
            for link in self.links:
                self._connect(link)
        except BaseException:
            self.close()
            raise

    # plumbing -------------------------------------------------------------------------------
    def _spin_until(self, done, what: str, link: _SimNodeLink | None = None, timeout: float | None = None):
        t_end = time.monotonic() + (self.timeout if timeout is None else timeout)
        while True:
            value = done()
            if value is not None and value is not False:
                return value
            if time.monotonic() > t_end:
                who = f"sim node {link.label}" if link else "the sim nodes"
                extra = f"; last bad message: {link.last_error}" if link is not None and link.last_error else ""
                raise TimeoutError(f"{who}: no answer within {self.timeout if timeout is None else timeout:g} s "
                                   f"while waiting for {what}{extra}. Is it running, in lockstep mode? "
                                   + start_hint(link.namespace if link else None))
            self.executor.spin_once(timeout_sec=0.05)

    def _future(self, fut, what: str, link: _SimNodeLink):
        self._spin_until(lambda: fut.done(), what, link)
        exc = fut.exception()
        if exc is not None:
            raise RuntimeError(f"sim node {link.label}: {what} failed: {exc}")
        return fut.result()

    def _call_idempotent(self, make_future, what: str, link: _SimNodeLink, attempt_s: float = 3.0):
        """An idempotent service call (reading or setting a parameter), sent again every
        `attempt_s` until it is answered or self.timeout passes. A request that reaches a node
        before its DDS participant has matched our reply reader gets no answer at all (Fast DDS
        drops the response: "failed to send response (timeout)" in the node's log); at start-up,
        with both sides still discovering each other, that happens, and waiting on the first
        request alone would hang for the whole timeout."""
        t_end = time.monotonic() + self.timeout
        while True:
            fut = make_future()
            left = t_end - time.monotonic()
            try:
                self._spin_until(lambda: fut.done(), what, link, timeout=max(0.05, min(attempt_s, left)))
            except TimeoutError:
                fut.cancel()
                if time.monotonic() >= t_end:
                    raise TimeoutError(f"sim node {link.label}: no answer within {self.timeout:g} s while waiting for "
                                       f"{what} (asked every {attempt_s:g} s). Is it running, in lockstep mode? "
                                       + start_hint(link.namespace)) from None
                continue
            exc = fut.exception()
            if exc is not None:
                raise RuntimeError(f"sim node {link.label}: {what} failed: {exc}")
            return fut.result()

    def _connect(self, link: _SimNodeLink) -> None:
        from rclpy.parameter import Parameter, parameter_value_to_python

        t_end = time.monotonic() + self.timeout
        while not link.reset_client.wait_for_service(timeout_sec=0.05):
            self.executor.spin_once(timeout_sec=0.0)
            if time.monotonic() > t_end:
                raise TimeoutError(f"no sim node answers at {link.fqn} (its reset service {link.fqn}/reset did not "
                                   f"appear within {self.timeout:g} s); " + start_hint(link.namespace))
        # one sim node serves one learner: another publisher on its /cmd (a learner, a policy node,
        # teleop) would step it between our commands (caught later too: every transition names
        # the command it was taken with)
        # This environment's own context is a new DDS participant: the others' endpoints arrive by
        # discovery. Wait until the sim node's own /cmd subscription is known, then 1 s more for the
        # other participants' (0.3 s in all, until 2026-11-28, missed a stray publisher on a loaded
        # 2-core machine)
        t_pub = time.monotonic() + 1.0
        while (time.monotonic() < t_pub or self.node.count_subscribers(f"{link.prefix}/cmd") < 1) \
                and time.monotonic() < t_end:
            self.executor.spin_once(timeout_sec=0.05)
        # (another environment of this same process is let through: gymnasium's check_env makes a
        # second one only to close it; one that steps is still caught by the command check)
        mine = f"lhd_ros_env_{os.getpid()}_"
        others = self._cmd_publishers_in_own_graph(link, mine, wait_names_s=min(2.0, t_end - time.monotonic()))
        # ... and as the sim node sees them: its participant has run longer than ours, which on a loaded
        # machine may not have discovered another process's publisher within the wait above (a CI run,
        # 2026-12-01, let a second learner through)
        if not others:
            others = self._cmd_publishers_seen_by_sim_node(link, mine)
        if others:
            raise RuntimeError(f"sim node {link.fqn} already has other publishers on {link.prefix}/cmd ({', '.join(others)}: "
                               "another learner, a policy node or teleop): one sim node serves one learner; start "
                               "another sim node (lhd up sim --count N) or stop the other publisher")
        if not link.params.wait_for_services(timeout_sec=self.timeout):
            raise TimeoutError(f"sim node {link.fqn}: its parameter services did not answer within {self.timeout:g} s")
        res = self._call_idempotent(lambda: link.params.get_parameters(["mode", "publish_transitions", "slopes_deg"]),
                                    "its parameters", link)
        mode, pub, slopes = (parameter_value_to_python(v) for v in res.values)
        if slopes not in (None, "", []):
            raise RuntimeError(f"sim node {link.fqn} cycles through slopes_deg = {slopes!r}; a learner sets each "
                               "episode's slope itself: start the sim node without slopes_deg")
        if mode != "lockstep":
            raise RuntimeError(f"sim node {link.fqn} runs in {mode!r} mode; a learner needs mode:=lockstep "
                               "(one control period per command, deterministic)")
        if not pub:
            raise RuntimeError(f"sim node {link.fqn} was started with publish_transitions:=false; a learner needs "
                               "its <prefix>/rl/transition")
        res = self._call_idempotent(lambda: link.params.set_parameters([Parameter("auto_reset", value=False)]),
                                    "auto_reset:=false", link)
        if not res.results[0].successful:
            raise RuntimeError(f"sim node {link.fqn} refused auto_reset:=false: {res.results[0].reason}")
        kv = self._spin_until(link.latest_status, "its first /episode status", link)
        theirs = kv.get("config_hash")
        if theirs is not None and theirs != self.hash:
            raise RuntimeError(f"sim node {link.fqn} reads another parameter file (config hash {theirs[:12]}) than "
                               f"this learner ({self.hash[:12]}); start both with the same --config / LHD_CONFIG")
        if theirs is None:
            raise RuntimeError(f"sim node {link.fqn} does not report its config hash in /episode (an older "
                               "lhd_sim_node?); update it")
        theirs_task = kv.get("task_hash")
        if theirs_task is None:
            raise RuntimeError(f"sim node {link.fqn} does not report its task hash in /episode (an older "
                               "lhd_sim_node?); update it")
        if theirs_task != self.task_hash:
            # config_hash leaves the reward's shaping keys out (they are not what the actor sees), but the sim node
            # computes the rewards this learner trains on and its card records
            raise RuntimeError(f"sim node {link.fqn} computes its reward from another task section (task hash "
                               f"{theirs_task[:12]}) than this learner ({self.task_hash[:12]}): the same actor inputs, "
                               "but other reward settings (e.g. midgoal_from_pile, reward_zones_from_pile, the tilt "
                               "schedule); start both with the same --config / LHD_CONFIG")

    def _cmd_publishers_in_own_graph(self, link: _SimNodeLink, mine: str, wait_names_s: float) -> list[str]:
        """The other publishers on the sim node's /cmd as this learner's participant knows them. A
        publisher's endpoint may arrive before its node's name (rmw reports _NODE_NAME_UNKNOWN_ until the
        participant's node list does): wait up to `wait_names_s` for the names, so the refusal names the
        node and another environment of this process is told apart (a CI run, 2026-11-29, refused an
        unnamed one)."""
        t_names = time.monotonic() + wait_names_s
        while True:
            infos = self.node.get_publishers_info_by_topic(f"{link.prefix}/cmd")
            if not any(i.node_name == UNKNOWN_NODE_NAME for i in infos) or time.monotonic() >= t_names:
                break
            self.executor.spin_once(timeout_sec=0.05)
        return [f"{i.node_namespace.rstrip('/')}/{i.node_name}" if i.node_name != UNKNOWN_NODE_NAME
                else "a node whose name DDS has not reported yet"
                for i in infos if not i.node_name.startswith(mine)]

    def _cmd_publishers_seen_by_sim_node(self, link: _SimNodeLink, mine: str) -> list[str]:
        """The other publishers on the sim node's /cmd as its own participant knows them (its
        ~/cmd_publishers service; ours are told apart by GID and by name). The sim node also remembers a
        publisher whose process was killed until that participant's DDS lease runs out (Fast DDS: 20 s),
        which a fresh participant never sees. So a publisher the sim node alone names is waited on, up to
        the timeout, until this learner's participant sees it too (refused: a live one, found late) or the
        sim node forgets it (let through: a dead one)."""
        t_end = time.monotonic() + self.timeout
        while not link.publishers_client.wait_for_service(timeout_sec=0.05):
            self.executor.spin_once(timeout_sec=0.0)
            if time.monotonic() > t_end:
                raise TimeoutError(f"sim node {link.fqn} has no {link.fqn}/cmd_publishers service (an older "
                                   "lhd_sim_node?); update it")
        while True:
            own = {bytes(i.endpoint_gid).hex() for i in self.node.get_publishers_info_by_topic(f"{link.prefix}/cmd")
                   if i.node_name == self.node.get_name()}
            res = self._call_idempotent(lambda: link.publishers_client.call_async(link._trigger.Request()),
                                        f"its {link.prefix}/cmd publishers", link)
            try:
                seen = json.loads(res.message)
                theirs = [e["node"] for e in seen if e["gid"] not in own
                          and not (e["node"] or "").rsplit("/", 1)[-1].startswith(mine)]
            except (ValueError, TypeError, KeyError, AttributeError) as exc:
                raise RuntimeError(f"sim node {link.fqn}: its cmd_publishers answer {res.message[:200]!r} is not "
                                   f"the expected JSON list of {{node, gid}} ({exc})") from None
            if not theirs:
                return []
            ours_too = self._cmd_publishers_in_own_graph(link, mine, wait_names_s=0.5)
            if ours_too:
                return ours_too
            if time.monotonic() >= t_end:
                return [f"{n or 'a node whose name DDS has not reported yet'}, seen by the sim node only for "
                        f"{self.timeout:g} s" for n in theirs]
            self._spin_for(0.25)

    def _spin_for(self, seconds: float) -> None:
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            self.executor.spin_once(timeout_sec=0.05)

    # the task -------------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this ROS environment is closed (close() was called); make a new one")

    def reset(self, i: int, seed: int, slope_deg: float | None = None, material: str | None = None) -> tr.Transition:
        """Start a new episode on sim node i with `seed` (and a slope in degrees / a material; None:
        drawn by the simulator, as LhdLoading-v0 does); returns its step-0 transition."""
        from rclpy.parameter import Parameter

        self._check_open()
        link = self.links[i]
        seed = int(seed)
        if not 0 <= seed < 2**31:
            raise ValueError(f"seed {seed} out of range; expected 0 <= seed < 2^31 (the sim node's next_seed)")
        # slope and material first, and only when they change (the sim node logs each change); the
        # seed last, so a refused slope leaves no seed set for someone else's next episode
        changes = []
        for name, value in (("slope_deg", -1.0 if slope_deg is None else float(slope_deg)),
                            ("material", "random" if material is None else str(material))):
            if link.set_values.get(name) != value:
                changes.append(Parameter(name, value=value))
        for params in ([changes] if changes else []) + [[Parameter("next_seed", value=seed)]]:
            res = self._future(link.params.set_parameters(params), ", ".join(p.name for p in params), link)
            for p, r in zip(params, res.results):
                if not r.successful:
                    link.set_values.clear()
                    raise ValueError(f"sim node {link.fqn} refused {p.name} = {p.value!r}: {r.reason}")
                link.set_values[p.name] = p.value
        before = link.episode
        self._future(link.reset_client.call_async(self._trigger_request(link)), "its reset service", link)

        def started():
            cands = [t for (e, s), t in link.transitions.items() if s == 0 and e > before and t.seed == seed]
            return max(cands, key=lambda t: t.episode) if cands else None

        t = self._spin_until(started, f"the first state of the episode with seed {seed}", link)
        link.episode, link.steps, link.seed, link.done = t.episode, 0, seed, False
        return t

    @staticmethod
    def _trigger_request(link):
        return link._trigger.Request()

    def actuator(self, action) -> np.ndarray:
        a = validate_action(action)
        a = apply_variant_filter(a, self.variant, self.p, deploy=self.deploy_filter)
        return np.asarray(to_actuator(a, self.p), dtype=np.float64)

    def step(self, actions: dict[int, Any]) -> dict[int, tuple[tr.Transition, dict | None]]:
        """One control period on each sim node i in `actions` (i -> action in [-1, 1]^3), all sent
        before any answer is awaited (the simulators step in parallel). Returns i -> (transition,
        the /episode values at the episode's end or None)."""
        self._check_open()
        sent, sent_u = {}, {}
        for i, a in actions.items():
            link = self.links[i]
            if link.done:
                raise RuntimeError(f"sim node {link.label}: step on a finished episode; reset first")
            u = self.actuator(a)
            sent_u[i] = u
            link.pub.publish(link._msg(data=[float(v) for v in u]))
            sent[i] = (link.episode, link.steps + 1)
        out = {}
        for i, key in sent.items():
            link = self.links[i]

            def arrived(link=link, key=key):
                t = link.transitions.get(key)
                if t is None and any(e > key[0] for e, _ in link.transitions):
                    raise RuntimeError(f"sim node {link.label} started another episode during ours (episode "
                                       f"{key[0]}); was it reset by someone else, or restarted?")
                return t

            t = self._spin_until(arrived, f"the state after step {key[1]} of episode {key[0]}", link)
            if not np.allclose(t.command, sent_u[i], rtol=0.0, atol=1e-9):
                link.done = True
                raise RuntimeError(f"sim node {link.label} took step {key[1]} of episode {key[0]} with command "
                                   f"{t.command.tolist()}, not this learner's {sent_u[i].tolist()}: another node publishes "
                                   f"on {link.prefix}/cmd (a second learner, a policy node, teleop). One sim node "
                                   "serves one learner; the transitions from here on would not be ours")
            end = None
            if t.terminated or t.truncated:
                end = self._spin_until(lambda link=link, key=key: link.statuses.get(key),
                                       f"the /episode result of episode {key[0]}", link)
            link.steps, link.done = key[1], bool(t.terminated or t.truncated)
            out[i] = (t, end)
        return out

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        import rclpy

        try:
            if hasattr(self, "node"):
                self.node.destroy_node()
        finally:
            if self.context.ok():
                rclpy.shutdown(context=self.context)

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


class LhdLoadingRosEnv(gym.Env):
    """LhdLoading-v0's task through one running sim node (see the module docstring).

    namespace: None for the un-namespaced sim node, else e.g. "/sim0". timeout: seconds to wait
    for any answer (TimeoutError saying what was awaited and how to start a sim node).
    slope_deg / material: as in LhdLoading-v0 (None: drawn per episode by the simulator);
    reset(options={"slope_deg": ..., "material": ...}) overrides them for one episode.
    info: outcome, namespace, seed, and at the episode's end loaded_mass, alpha_deg, material and
    episode_result (task.metrics.EpisodeResult from /episode)."""

    metadata = {"render_modes": [], "render_fps": 10}

    def __init__(self, variant: str = "rld", config=None, namespace: str | None = None,
                 timeout: float = DEFAULT_TIMEOUT_S, slope_deg: float | None = None, material: str | None = None,
                 deploy_filter: bool = False):
        self.pool = SimNodePool([namespace], variant, config, timeout, deploy_filter)
        self.cfg, self.p, self.variant = self.pool.cfg, self.pool.p, variant
        self.slope_deg, self.material, self.namespace = slope_deg, material, namespace
        self.observation_space = gym.spaces.Box(OBS_LOW, OBS_HIGH, dtype=np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self._done = True

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"slope_deg", "material"}
        if unknown:
            raise ValueError(f"options {sorted(unknown)} are not supported through ROS; expected slope_deg, material "
                             "(randomised conditions come from the sim node's parameter file)")
        if seed is None:      # continue the environment's own stream, as the in-process env does
            seed = int(self.np_random.integers(0, 2**31 - 1))
        t = self.pool.reset(0, seed, options.get("slope_deg", self.slope_deg), options.get("material", self.material))
        self._done = False
        return t.obs, self._info(t, None)

    def step(self, action):
        if self._done:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        t, end = self.pool.step({0: action})[0]
        self._done = t.terminated or t.truncated
        return t.obs, t.reward, t.terminated, t.truncated, self._info(t, end)

    def _info(self, t: tr.Transition, end: dict | None) -> dict:
        link = self.pool.links[0]
        # deterministic for a seed (check_env): the sim node's episode index and stamps are not in it
        # (they depend on what the node ran before; env.pool.links[0].episode has the index)
        info = {"namespace": link.label, "seed": t.seed, "outcome": "running"}
        if end is not None:
            info["episode_result"] = result_from_status(end)
            info["outcome"] = end["state"] if t.terminated else "running"
            info["loaded_mass"] = float(end["loaded_mass"])
            info["alpha_deg"] = float(end["slope_deg"])
            info["material"] = end["material"]
        return info

    def close(self):
        self.pool.close()
