"""ROS 2 parameter files (YAML) read as rcl applies them, without rclpy: which sections reach a node.

The shipped files key their sections `/**/<node name>` (config/real_machine.yaml, config/*_node.yaml): rcl
matches a bare `<node name>` only in the root namespace, so under `-r __ns:=/lhd2` or a launch file's
PushRosNamespace every calibrated value fell back to the node's default without a word (a review, 2026-11-29).
The launchers' checks (`lhd up real`) and the twin (its camera and LiDAR poses) read the same sections here.
"""
from __future__ import annotations

import re


def rcl_node_pattern(name: str) -> re.Pattern:
    """A parameter file's node key as rcl matches it against a node's fully qualified name: a
    leading / is implied, `*` is one name token, `**` any number of them (`/**` every node)."""
    name = name if name.startswith("/") else "/" + name
    rx = re.escape(name).replace(r"/\*\*", "(?:/[^/]+)*").replace(r"/\*", "/[^/]+")
    return re.compile(rx + r"\Z")


def param_sections(doc, prefix: str = ""):
    """(node key, ros__parameters) of a parameter file in file order, nested keys joined
    (`/**: {lhd_policy: {ros__parameters: ...}}` is `/**/lhd_policy`)."""
    if not isinstance(doc, dict):
        return
    for key, val in doc.items():
        if not isinstance(val, dict):
            continue
        name = f"{prefix}/{str(key).strip('/')}" if prefix else str(key)
        if isinstance(val.get("ros__parameters"), dict):
            yield name, val["ros__parameters"]
        yield from param_sections({k: v for k, v in val.items() if k != "ros__parameters"}, name)


def params_of(doc, node: str) -> dict:
    """The ROS parameters the parsed parameter file `doc` gives the node `node` (fully qualified, e.g.
    /lhd_policy or /lhd2/lhd_policy; a bare name is in the root namespace), as rcl applies them: every
    section whose key matches, in file order, a later one over an earlier."""
    fqn = node if node.startswith("/") else "/" + node
    out: dict = {}
    for key, params in param_sections(doc):
        if rcl_node_pattern(key).match(fqn):
            out.update(params)
    return out
