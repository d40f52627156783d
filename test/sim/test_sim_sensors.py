"""The twin's simulated sensors and marker geometry (lhd_sim_node/sim_sensors.py), without ROS.
Expected values are computed by hand in the tests (pinhole geometry, ray/line intersections);
the simulator supplies real poses and piles. The accuracy through the real nodes is in
test_sim_sensors_ros.py."""
import ast
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from lhd_loading_ros.ros.params_file import params_of
from lhd_loading_ros.perception.aruco import MarkerDetector
from lhd_loading_ros.perception.synthetic import DrawPoint
from lhd_loading_ros.task.zones import Zones
from lhd_sim_node.sim_sensors import (ARUCO_DEFAULTS, LIDAR_DEFAULTS, CameraModel, LidarModel, TipTrail, camera_image,
                                      fee_arrow, lidar_scan, machine_segments, pile_profile, pile_surfaces, zone_boxes)
from lhd_sim_node.simulator import LhdSimulator

ROOT = Path(__file__).resolve().parents[2]
NODES = ROOT / "lhd_loading_ros" / "lhd_loading_ros" / "nodes"
# the sections as rcl gives them to the nodes (the file keys them /**/<node>: ros/params_file.py)
MACHINE = {n: {"ros__parameters": params_of(yaml.safe_load((ROOT / "config" / "real_machine.yaml").read_text()), "/" + n)}
           for n in ("aruco_pose_node", "lidar_slope_node", "lhd_hw_bridge", "end_zone_node", "lhd_supervisor",
                     "lhd_policy")}
CAM = {"camera_xyz": [-1.3, 0.0, 2.0]}          # above the marker's path during an attempt
IDENTITY = (1.0, 0.0, 0.0, 0.0)                 # MuJoCo quaternion order w, x, y, z


@pytest.fixture(scope="module")
def sim(cfg_session):
    s = LhdSimulator(cfg_session)
    s.reset(np.random.default_rng(3), alpha=math.radians(20.0), material="homogeneous")
    return s


def _node_defaults(path: Path) -> dict:
    """Param("name", default, ...) of a node's source, read without importing it (no ROS here)."""
    out = {}
    for call in ast.walk(ast.parse(path.read_text())):
        if isinstance(call, ast.Call) and getattr(call.func, "id", None) == "Param" and len(call.args) >= 2:
            try:
                out[ast.literal_eval(call.args[0])] = ast.literal_eval(call.args[1])
            except ValueError:   # an expression such as math.pi: evaluate it with math only
                out[ast.literal_eval(call.args[0])] = eval(compile(ast.Expression(call.args[1]), "p", "eval"),
                                                           {"math": math})
    return out


def test_defaults_are_the_real_nodes_defaults():
    aruco = _node_defaults(NODES / "aruco_pose_node.py")
    lidar = _node_defaults(NODES / "lidar_slope_node.py")
    for k, v in ARUCO_DEFAULTS.items():
        assert aruco[k] == pytest.approx(v) if not isinstance(v, str) else aruco[k] == v, k
    for k, v in LIDAR_DEFAULTS.items():
        assert lidar[k] == pytest.approx(v), k


# ------------------------------------------------------------------------------ camera
def test_marker_pose_is_base_link_composed_with_the_inverse_of_marker_to_base():
    cam = CameraModel.from_params(MACHINE["aruco_pose_node"])
    # marker_to_base_xyz = (0.10, 0, -0.213): base_link 0.10 m ahead of and 0.213 m below the marker
    T = cam.marker_pose((1.0, 0.5, 0.137), IDENTITY)
    assert T[:3, 3] == pytest.approx([0.90, 0.5, 0.350])
    assert T[:3, :3] == pytest.approx(np.eye(3))
    # machine yawed by +90 deg: "behind" is -y, so the marker is at (0, -0.10, 0.213) from base_link
    c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
    T = cam.marker_pose((0.0, 0.0, 0.0), (c, 0.0, 0.0, s))
    assert T[:3, 3] == pytest.approx([0.0, -0.10, 0.213], abs=1e-12)
    # marker_to_base with a rotation: base_link yawed +90 deg in the marker frame, so the marker
    # is yawed -90 deg in base_link; base_link at the origin: marker at -R^T t
    sec = {"ros__parameters": {"marker_to_base_xyz": [0.1, 0.2, -0.2], "marker_to_base_rpy": [0, 0, math.pi / 2]}}
    T = CameraModel.from_params(sec).marker_pose((0, 0, 0), IDENTITY)
    # R = Rz(90): R^T (0.1, 0.2, -0.2) = (0.2, -0.1, -0.2) -> marker at (-0.2, 0.1, 0.2)
    assert T[:3, 3] == pytest.approx([-0.2, 0.1, 0.2], abs=1e-12)
    assert T[:3, :3] == pytest.approx(np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]]), abs=1e-12)


def test_marker_is_where_the_pinhole_puts_it_and_decodes(sim):
    cam = CameraModel.from_params({**MACHINE["aruco_pose_node"]["ros__parameters"], **CAM}, noise=2.0, blur=1.0)
    pos, quat = sim.data.qpos[:3].copy(), sim.data.qpos[3:7].copy()
    img = camera_image(cam, pos, quat, np.random.default_rng(0))
    assert img.shape == (480, 640) and img.dtype == np.uint8
    corners = MarkerDetector("DICT_4X4_50", 7, 0.12).detect(img)
    assert corners is not None
    # by hand: f = 0.94 * 640 = 601.6 px; the camera looks down from (-1.3, 0, 2.0), rpy (pi, 0, 0):
    # optical x = +x, optical y = -y, optical z = -z, so image right = +x and image down = -y; the
    # marker centre is 0.10 m behind base_link, 0.213 m above it (the machine stands level at
    # rest), so depth d = 2.0 - z_m, u = 320 + f (x_m + 1.3) / d, v = 240 - f y_m / d
    xm, ym, zm = pos[0] - 0.10, pos[1], pos[2] + 0.213
    d = 2.0 - zm
    u, v = 320 + 601.6 * (xm + 1.3) / d, 240 - 601.6 * ym / d
    # within a quarter pixel (area-integrated rendering, sub-pixel corners: < 0.7 mm at 1.6 m)
    assert corners.mean(axis=0) == pytest.approx([u, v], abs=0.25)
    side = 601.6 * 0.12 / d                                      # px, the black square's side
    assert np.linalg.norm(corners[1] - corners[0]) == pytest.approx(side, abs=0.6)
    assert cam.visible(pos, quat)
    assert not cam.visible((pos[0] + 3.0, 0.0, pos[2]), quat)       # driven 3 m on: out of the image


def test_the_configured_marker_height_is_the_simulated_machines(sim):
    """The ArUco node's marker_height (config/real_machine.yaml) is where the twin's marker is
    with the machine standing on the floor: rear axle height (the wheel radius, base_link's
    z at rest) plus the marker's 0.213 m above it."""
    aruco = MACHINE["aruco_pose_node"]["ros__parameters"]
    cam = CameraModel.from_params(aruco)
    z = cam.marker_pose(sim.data.qpos[:3], sim.data.qpos[3:7])[2, 3]
    assert aruco["marker_height"] == pytest.approx(z, abs=0.005)
    assert aruco["marker_height"] == pytest.approx(0.137 + 0.213, abs=0.005)


def test_exposure_noise_and_dropped_frames():
    sec = {"camera_xyz": [-1.3, 0.0, 2.0]}
    pose = ((-1.3 + 0.10, 0.0, 0.137), IDENTITY)                    # marker right under the camera
    clean = CameraModel.from_params(sec, noise=0.0, blur=0.0)
    dark = CameraModel.from_params(sec, noise=0.0, blur=0.0, exposure=0.5, offset=10.0)
    a = camera_image(clean, *pose, np.random.default_rng(0)).astype(float)
    b = camera_image(dark, *pose, np.random.default_rng(0)).astype(float)
    # gain 0.5 and offset 10 grey levels on every pixel (rounding to integers: within 1)
    assert np.abs(b - (0.5 * a + 10.0)).max() <= 1.0 + 1e-9
    assert a.max() == 255 and b.max() == pytest.approx(0.5 * 255 + 10, abs=1)   # the marker's white quiet zone
    noisy = CameraModel.from_params(sec, noise=4.0, blur=0.0)
    c = camera_image(noisy, *pose, np.random.default_rng(1)).astype(float)
    mid = (a > 20) & (a < 235)                                       # unclipped grey levels
    assert np.std(c[mid] - a[mid]) == pytest.approx(4.0, rel=0.05)
    lossy = CameraModel.from_params(sec, dropout=0.3)
    rng = np.random.default_rng(2)
    lost = sum(camera_image(lossy, *pose, rng) is None for _ in range(300))
    assert 60 <= lost <= 120                                         # 90 expected, +-3.5 sigma
    # a marker behind the camera: only the floor, no marker
    behind = camera_image(clean, (-1.2, 0.0, 3.0), IDENTITY, np.random.default_rng(0))
    assert MarkerDetector("DICT_4X4_50", 7, 0.12).detect(behind) is None


@pytest.mark.parametrize("kw, msg", [
    (dict(f=-1.0), "focal length"), (dict(noise=-1.0), "noise"), (dict(dropout=1.0), "dropout"),
    (dict(exposure=0.0), "exposure"), (dict(width=4), "16x16"), (dict(blur=float("nan")), "blur"),
])
def test_camera_bad_parameters_say_what_is_wrong(kw, msg):
    with pytest.raises(ValueError, match=msg):
        CameraModel.from_params({}, **kw)


def test_camera_bad_section_names_the_key():
    with pytest.raises(ValueError, match="camera_xyz"):
        CameraModel.from_params({"camera_xyz": [1.0, 2.0]})
    with pytest.raises(ValueError, match="dictionary"):
        CameraModel.from_params({"dictionary": "DICT_NOPE"})
    with pytest.raises(ValueError, match="sensor_rpy"):
        LidarModel.from_params({"sensor_rpy": [0.0, float("nan"), 0.0]})


def test_camera_info_is_the_pinhole():
    info = CameraModel.from_params({}, width=320, height=240, f=300.0).camera_info()
    assert info["k"] == [300.0, 0.0, 160.0, 0.0, 300.0, 120.0, 0.0, 0.0, 1.0]
    assert info["p"] == [300.0, 0.0, 160.0, 0.0, 0.0, 300.0, 120.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    assert (info["width"], info["height"], info["d"]) == (320, 240, [0.0] * 5)


# ------------------------------------------------------------------------------ LiDAR
def _model(**kw):
    """1 deg beams from -170 to -10 deg (index 80 is straight down), no noise."""
    base = dict(n=161, noise=0.0, outliers=0.0)
    base.update(kw)
    return LidarModel.from_params(MACHINE["lidar_slope_node"], **base)


def test_rays_hit_the_pile_the_floor_and_the_cut(cfg_session):
    s = LhdSimulator(cfg_session)
    s.new_pile(np.random.default_rng(0), alpha=math.radians(20.0), material="homogeneous")
    lid = _model()
    r, a0, inc = lidar_scan(lid, s.pile, np.random.default_rng(0))
    assert a0 == pytest.approx(-math.radians(170)) and inc == pytest.approx(math.radians(1))
    t20 = math.tan(math.radians(20.0))
    # straight down from (0.6, 1.6): the intact face at x = 0.6 is 0.6 tan 20 high
    assert r[80] == pytest.approx(1.6 - 0.6 * t20, abs=1e-9)
    # -135 deg (toward -x, 45 deg down): the floor at x = 0.6 - 1.6 = -1.0, before the toe
    assert r[35] == pytest.approx(1.6 * math.sqrt(2.0), abs=1e-9)
    # -10 deg, nearly level toward +x: above the crest (h = 0.68) it reaches the back wall at
    # L + 0.3 = 0.68 / tan 20 + 0.3, where the beam has dropped tan(10 deg) per metre
    back = 0.68 / t20 + 0.3
    assert r[160] == pytest.approx((back - 0.6) / math.cos(math.radians(10)), abs=1e-9)
    # the bucket cut the columns up to x = 1.0 down to 0.05 m: straight down now ends there
    s.pile.top[:, s.pile.x_centers < 1.0] = 0.05
    r, _, _ = lidar_scan(lid, s.pile, np.random.default_rng(0))
    assert r[80] == pytest.approx(1.6 - 0.05, abs=1e-9)
    # the profile of the cut slice: toe, the cut, the face from the first intact column, crest, back wall
    prof = pile_profile(s.pile, 0.0)
    assert prof[0] == pytest.approx([0, 0]) and prof[-1] == pytest.approx([back, 0.68])
    i = np.searchsorted(s.pile.x_centers, 1.0)
    assert prof[1:i + 1, 1] == pytest.approx(0.05) and prof[i + 1, 1] == pytest.approx(s.pile.x_centers[i] * t20)


def test_range_limits_ceiling_noise_and_outliers(cfg_session):
    s = LhdSimulator(cfg_session)
    s.new_pile(np.random.default_rng(0), alpha=math.radians(25.0), material="homogeneous")
    short = _model(range_max=1.0)
    r, _, _ = lidar_scan(short, s.pile, np.random.default_rng(0))
    assert np.isinf(r[80])                                          # 1.6 - 0.6 tan 25 = 1.32 m > 1 m
    up = _model(angle_min=math.radians(80), angle_max=math.radians(100), n=21)
    r, _, _ = lidar_scan(up, s.pile, np.random.default_rng(0), clutter=DrawPoint(ceiling_z=2.0, brow_x=0.2))
    # straight up from (0.6, 1.6): the brow at x = 0.2, so above the sensor is the drawbell's
    # front wall rising at 45 deg from (0.2, 2.0): z = 2.0 + (0.6 - 0.2) = 2.4 -> 0.8 m
    assert r[10] == pytest.approx(0.8, abs=1e-9)
    # the brow at x = 0.7: the sensor is under the flat ceiling at 2.0 m -> 0.4 m
    r_ceil, _, _ = lidar_scan(up, s.pile, np.random.default_rng(0), clutter=DrawPoint(ceiling_z=2.0, brow_x=0.7))
    assert r_ceil[10] == pytest.approx(0.4, abs=1e-9)
    r_open, _, _ = lidar_scan(up, s.pile, np.random.default_rng(0))
    assert np.isinf(r_open[10])                                     # no draw point: nothing above
    exact, _, _ = lidar_scan(_model(n=721), s.pile, np.random.default_rng(0))
    noisy, _, _ = lidar_scan(_model(n=721, noise=0.01), s.pile, np.random.default_rng(1))
    ok = np.isfinite(exact)
    assert np.std(noisy[ok] - exact[ok]) == pytest.approx(0.01, rel=0.15)
    dusty, _, _ = lidar_scan(_model(n=2000, outliers=0.1), s.pile, np.random.default_rng(2))
    exact2, _, _ = lidar_scan(_model(n=2000), s.pile, np.random.default_rng(2))
    frac = np.mean(~np.isclose(dusty, exact2, rtol=0.0, atol=1e-6))     # inf == inf: unchanged
    assert 0.07 < frac < 0.13


def test_the_machine_hides_what_is_behind_it(sim):
    lid = _model()
    occ = machine_segments(sim.model, sim.data)
    assert len(occ) >= 16                                           # 4 boxes and the boom crossing y = 0
    d = sim.data
    g = sim.model.geom("rear_body").id
    top = d.geom_xpos[g] + d.geom_xmat[g].reshape(3, 3)[:, 2] * sim.model.geom_size[g][2]   # centre of its roof
    # a beam from the sensor aimed at the centre of the rear body's roof stops there (the ray
    # passes above the front body and the boom, checked by their heights below the line)
    o = np.array([0.6, 1.6])
    dx, dz = top[0] - o[0], top[2] - o[1]
    ang = math.atan2(dz, dx)              # in the pile's XZ plane = the scanner's angle (roll 90 deg)
    one = LidarModel.from_params(MACHINE["lidar_slope_node"], n=2, angle_min=ang, angle_max=ang + 1e-6,
                                 noise=0.0, outliers=0.0)
    r, _, _ = lidar_scan(one, sim.pile, np.random.default_rng(0), occluders=occ)
    assert r[0] == pytest.approx(math.hypot(dx, dz), abs=1e-6)
    r_free, _, _ = lidar_scan(one, sim.pile, np.random.default_rng(0))
    assert r_free[0] > r[0] + 0.1                                   # without the machine: the floor beyond


# ------------------------------------------------------------------------------ markers
def test_pile_surfaces_zone_boxes_trail_and_arrow(sim):
    surf = pile_surfaces(sim.pile)
    assert len(surf) == sim.pile.n_y
    for j, line in enumerate(surf):
        assert line[:, 1] == pytest.approx(sim.pile.y_centers[j])
        assert line[-1, 2] == pytest.approx(sim.pile.h)
    z = Zones(x_min=0.5, x_max=0.9, z_min=0.35, x_cutoff=1.77, x_obs_start=-0.1, x_obs_end=1.0, y_half=0.2, z_top=0.4)
    boxes = {n: (c, s) for n, c, s in zone_boxes(z)}
    assert boxes["end"][0] == pytest.approx([0.7, 0.0, 0.55]) and boxes["end"][1] == pytest.approx([0.4, 0.4, 0.4])
    assert boxes["permitted"][0] == pytest.approx([0.45, 0.0, 0.2]) and boxes["permitted"][1] == pytest.approx([1.1, 0.4, 0.4])
    assert boxes["cutoff"][0][0] == pytest.approx(1.77)
    trail = TipTrail(spacing=0.01, max_points=3)
    assert trail.add((0, 0, 0)) and not trail.add((0.005, 0, 0)) and trail.add((0.02, 0, 0))
    assert not trail.add((float("nan"), 0, 0))
    trail.add((0.04, 0, 0))
    trail.add((0.06, 0, 0))
    assert trail.array()[:, 0] == pytest.approx([0.02, 0.04, 0.06])       # the last 3
    arrow = fee_arrow((1.0, 0.0, 0.1), (-800.0, 0.0, -400.0), scale=0.0005)
    assert arrow == pytest.approx(np.array([[1.0, 0.0, 0.1], [0.6, 0.0, -0.1]]))
    assert fee_arrow((1.0, 0.0, 0.1), (0.0, 0.0, 0.0)) is None
    fee = sim.last_fee                                                  # the simulator's report after the attack
    tip = sim.data.site_xpos[sim.sid_tip]
    a = fee_arrow(tip, fee.force)
    assert a is not None and a[1, 0] < a[0, 0]                           # the pile pushes the bucket back


def test_the_imu_reports_the_true_orientation_turned_by_its_error_in_its_own_frame():
    """sim_sensors.imu_orientation: q_true * q_err, with the error a roll then a pitch about the
    machine's own axes: the rotation matrix is R_true Rx(roll) Ry(pitch), built here by hand, for a
    yawed, pitched and rolled machine; zero error returns the truth."""
    import numpy as np

    from lhd_loading_ros.task.kinematics import quat_to_mat
    from lhd_sim_node.sim_sensors import imu_orientation

    def rx(a):
        return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])

    def ry(a):
        return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])

    def rz(a):
        return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    R_true = rz(math.radians(70)) @ ry(math.radians(9)) @ rx(math.radians(-3))
    from lhd_loading_ros.task.kinematics import mat_to_quat
    q_true = mat_to_quat(R_true)
    for roll, pitch in ((0.0, 0.0), (0.002, -0.003), (0.05, 0.1)):
        got = quat_to_mat(*imu_orientation(q_true, roll, pitch))
        assert np.allclose(got, R_true @ rx(roll) @ ry(pitch), atol=1e-12)
