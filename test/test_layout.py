"""The rooms of lhd_loading_ros and the direction of their imports (issue 12 §1): every import
of every module, including the lazy ones inside functions, read with `ast`."""
import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "lhd_loading_ros" / "lhd_loading_ros"
# room -> rooms it may import from (itself always allowed); cli is the top and may use anything
ALLOWED = {
    "task": set(),
    "policy": {"task"},
    "perception": {"task"},
    "ros": {"task"},
    "learning": {"task", "policy"},
    "nodes": {"task", "policy", "perception", "ros"},
    "cli": {"task", "policy", "perception", "ros", "learning", "nodes"},
}
ROS_FREE = {"task", "policy", "perception", "learning"}
ROS_MODULES = ("rclpy", "std_msgs", "sensor_msgs", "nav_msgs", "geometry_msgs", "diagnostic_msgs", "std_srvs",
               "rosgraph_msgs", "rcl_interfaces", "builtin_interfaces")


def _imports(path: Path, room: str):
    """Absolute names of every module imported by `path` (relative imports resolved)."""
    mod = ["lhd_loading_ros", room] + ([] if path.name == "__init__.py" else [path.stem])
    for n in ast.walk(ast.parse(path.read_text())):
        if isinstance(n, ast.Import):
            yield from (a.name for a in n.names)
        elif isinstance(n, ast.ImportFrom):
            if n.level:
                base = mod[: len(mod) - n.level]
                name = ".".join(base + ([n.module] if n.module else []))
            else:
                name = n.module
            yield name
            for a in n.names:      # from lhd_loading_ros import task
                yield f"{name}.{a.name}"


def test_the_package_has_only_rooms():
    loose = sorted(p.name for p in PKG.glob("*.py") if p.name != "__init__.py")
    assert loose == [], f"modules outside a room: {loose}"
    rooms = sorted(p.name for p in PKG.iterdir() if p.is_dir() and (p / "__init__.py").is_file())
    assert rooms == sorted(ALLOWED)


def test_no_room_imports_upward_and_the_core_is_ros_free():
    bad = []
    for room, allowed in ALLOWED.items():
        for path in sorted((PKG / room).rglob("*.py")):
            for name in _imports(path, room):
                parts = name.split(".")
                if parts[0] == "lhd_loading_ros" and len(parts) > 1 and parts[1] in ALLOWED:
                    if parts[1] != room and parts[1] not in allowed:
                        bad.append(f"{path.relative_to(PKG)} imports {name}")
                if room in ROS_FREE and parts[0] in ROS_MODULES:
                    bad.append(f"{path.relative_to(PKG)} (ROS-free room) imports {name}")
    assert not bad, "\n".join(bad)


def test_the_checker_sees_a_violation(tmp_path):
    """The test above can fail: an upward import written into a task module is found."""
    f = tmp_path / "x.py"
    f.write_text("def f():\n    from ..nodes.policy_node import PolicyNode\n    import rclpy\n")
    names = set(_imports(f, "task"))
    assert "lhd_loading_ros.nodes.policy_node" in names and "rclpy" in names
