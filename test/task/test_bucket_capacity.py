"""The bucket's geometric capacity (task/bucket_capacity.py) against calculations written here:
the struck prism by hand, the SAE J742 / ISO 7546 heaped rating by its hip-roof formula, the
retained volume at the attack pose and at 40 deg of curl by a brute-force 3-D grid (every rim
point's cone of repose, point-in-section tests), and physical properties over the pitch range."""
import copy
import math

import numpy as np
import pytest

from lhd_loading_ros.task.bucket_capacity import (bucket_section, capacity_table, fill_scale, heaped_volume,
                                                  sae_heaped_volume, struck_volume)
from lhd_loading_ros.task.config import ConfigError, validate

r = math.radians

# The config's bucket (machine: tip 0.30 m ahead of the hinge, back 0.26 m, width 0.40 m; plates 0.01 m):
# inside, the plate runs from the back wall's inner face (x = 0.005) to the lip (x = 0.30), the back
# wall rises 0.26 m above the plate's top face, the side plates' inner faces are 0.39 m apart.
PLATE = 0.30 - 0.005
BACK = 0.26
W = 0.40 - 0.01


def test_section_and_struck_volume_by_hand(cfg):
    sec = bucket_section(cfg["machine"])
    assert sec["plate_length"] == pytest.approx(PLATE) and sec["back_height"] == pytest.approx(BACK)
    assert sec["W"] == pytest.approx(W)
    v = 0.5 * PLATE * BACK * W          # triangle H T K times the width: 14.9565 L
    assert struck_volume(cfg["machine"]) == pytest.approx(v, rel=1e-9)
    assert v * 1e3 == pytest.approx(14.96, abs=0.01)            # the 14.96 L
    assert v * 1900.0 == pytest.approx(28.4, abs=0.05)         # ~28 kg struck at 1,900 kg/m^3
    # the strike plane is level when the bucket is curled back by atan(back / plate) = 41.4 deg
    assert math.degrees(sec["level_strike_pitch"]) == pytest.approx(math.degrees(math.atan2(BACK, PLATE)))


def hip_roof(a, b, tan_t):
    """Volume under z = tan_t * (distance to the border) over an a x b rectangle, a <= b."""
    a, b = min(a, b), max(a, b)
    return tan_t * a * a * (3 * b - a) / 12.0


def test_sae_rating_is_the_hip_roof(cfg):
    A = math.hypot(PLATE, BACK)          # strike plane length, 0.393 m (just above W: the ridge runs along x)
    vs = 0.5 * PLATE * BACK * W
    assert sae_heaped_volume(cfg["machine"]) == pytest.approx(vs + hip_roof(A, W, 0.5), rel=1e-6)
    assert sae_heaped_volume(cfg["machine"]) * 1e3 == pytest.approx(20.0, abs=0.1)   # the "about 20 L"
    # a wider bucket (A <= W): ISO 7546 / SAE J742's top volume A^2 W / 8 - A^3 / 24, literally
    wide = copy.deepcopy(cfg["machine"])
    wide["bucket_width"] = 0.60
    Ww = 0.59
    iso = 0.5 * PLATE * BACK * Ww + A * A * Ww / 8 - A ** 3 / 24
    assert sae_heaped_volume(wide) == pytest.approx(iso, rel=1e-6)


def test_closed_forms_at_attack_pose_and_full_curl(cfg):
    """Attack pose: the strike line drops to the lip at 41.4 deg, steeper than the repose theta, so
    the material's surface rises from the lip at theta and meets the back wall at PLATE tan theta
    (< BACK): a triangle. 90 deg of curl: the back wall is the floor, the back edge the lower rim,
    the surface rises from it at theta to the plate: a triangle BACK x BACK tan theta."""
    mc = cfg["machine"]
    for th in (30.0, 35.0, 38.0):
        t = math.tan(r(th))
        assert heaped_volume(0.0, mc, r(th)) == pytest.approx(0.5 * PLATE * PLATE * t * W, rel=1e-9)
        assert heaped_volume(r(90.0), mc, r(th)) == pytest.approx(0.5 * BACK * BACK * t * W, rel=1e-9)


def brute_force_volume(pitch, repose, n_x=150, n_y=78, n_z=160, n_rim=120):
    """Independent 3-D calculation: a regular grid of points over the bucket's bounding box; a point
    is held when it lies in the bucket's section (triangle H T K, or above the strike line within
    the rims' span when the opening faces up) and below the surface of repose, min over rim points
    (lip edge, back edge, both side edges on the strike line) of z_rim + tan(theta) * horizontal
    distance."""
    c, s = math.cos(pitch), math.sin(pitch)
    rot = lambda x, z: (x * c - z * s, x * s + z * c)  # noqa: E731  (tip up for pitch > 0)
    H, T, K = rot(0.0, 0.0), rot(PLATE, 0.0), rot(0.0, BACK)
    t = math.tan(repose)
    # rim points
    u = np.linspace(0.0, 1.0, n_rim)
    ys = np.linspace(-W / 2, W / 2, n_rim)
    rim = [np.column_stack([np.full(n_rim, T[0]), ys, np.full(n_rim, T[1])]),
           np.column_stack([np.full(n_rim, K[0]), ys, np.full(n_rim, K[1])])]
    for y in (-W / 2, W / 2):
        rim.append(np.column_stack([T[0] + u * (K[0] - T[0]), np.full(n_rim, y), T[1] + u * (K[1] - T[1])]))
    rim = np.concatenate(rim)
    xs_all = [H[0], T[0], K[0]]
    zs_all = [H[1], T[1], K[1]]
    x0, x1 = min(xs_all), max(xs_all)
    z0, z1 = min(zs_all), max(zs_all) + 0.3
    dx, dy, dz = (x1 - x0) / n_x, W / n_y, (z1 - z0) / n_z
    xc = x0 + (np.arange(n_x) + 0.5) * dx
    yc = -W / 2 + (np.arange(n_y) + 0.5) * dy
    zc = z0 + (np.arange(n_z) + 0.5) * dz
    X, Y = np.meshgrid(xc, yc, indexing="ij")
    d = np.hypot(X[..., None] - rim[:, 0], Y[..., None] - rim[:, 1])
    surf = np.min(rim[:, 2] + t * d, axis=-1)                         # (n_x, n_y)
    # point in triangle (barycentric), per (x, z)
    Xz, Zz = np.meshgrid(xc, zc, indexing="ij")

    def side(P, Q, x, z):
        return (Q[0] - P[0]) * (z - P[1]) - (Q[1] - P[1]) * (x - P[0])

    s1, s2, s3 = side(H, T, Xz, Zz), side(T, K, Xz, Zz), side(K, H, Xz, Zz)
    inside = ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))
    # above the strike line within the rims' span, when the opening faces up (H below the line T-K)
    lo_x, hi_x = min(T[0], K[0]), max(T[0], K[0])
    if hi_x - lo_x > 1e-9:
        z_line = T[1] + (K[1] - T[1]) * (Xz - T[0]) / (K[0] - T[0])
        z_line_H = T[1] + (K[1] - T[1]) * (H[0] - T[0]) / (K[0] - T[0])
        if H[1] < z_line_H:
            inside |= (Xz >= lo_x) & (Xz <= hi_x) & (Zz >= z_line)
    held = inside[:, None, :] & (zc[None, None, :] <= surf[..., None])
    return float(np.count_nonzero(held)) * dx * dy * dz


@pytest.mark.parametrize("pitch_deg", [0.0, 40.0, 20.0, 65.0])
def test_heaped_volume_against_brute_force(cfg, pitch_deg):
    rep = r(cfg["task"]["bucket_repose_deg"])
    v = heaped_volume(r(pitch_deg), cfg["machine"], rep)
    ref = brute_force_volume(r(pitch_deg), rep)
    assert v == pytest.approx(ref, rel=0.01), (pitch_deg, v, ref)


def test_physical_properties(cfg):
    mc = cfg["machine"]
    rep = r(cfg["task"]["bucket_repose_deg"])
    sec = bucket_section(mc)
    level = sec["level_strike_pitch"]
    pitches = np.radians(np.arange(-60.0, 90.01, 1.0))
    v = np.array([heaped_volume(float(p), mc, rep) for p in pitches])
    assert np.all(v >= 0.0)
    # tilting forward loses material: capacity never grows as the bucket tilts forward from the
    # level strike plane, nor as it curls back past it
    up = pitches <= level
    assert np.all(np.diff(v[up]) >= -1e-12)
    assert np.all(np.diff(v[~up]) <= 1e-12)
    # the most it holds: strike plane level, struck + heap (more than struck)
    v_level = heaped_volume(level, mc, rep)
    assert v.max() <= v_level + 1e-12 and v_level > sec["struck_volume"]
    # a plate tilted forward by more than the angle of repose sheds everything
    assert heaped_volume(-rep - r(1.0), mc, rep) == 0.0
    # a material that stands steeper heaps higher, at every pitch
    v_steep = np.array([heaped_volume(float(p), mc, rep + r(5.0)) for p in pitches])
    assert np.all(v_steep >= v - 1e-12) and v_steep.max() > v.max()
    with pytest.raises(ValueError):
        heaped_volume(0.0, mc, r(90.0))
    with pytest.raises(ValueError):
        heaped_volume(float("nan"), mc, rep)


def test_capacity_table(cfg):
    grid, vol = capacity_table(cfg)
    assert grid.shape == vol.shape and np.all(np.diff(grid) > 0)
    t = cfg["task"]
    assert grid[0] <= r(t["phi_shovel_min_deg"]) and grid[-1] >= r(t["phi_shovel_max_deg"])
    rep = r(t["bucket_repose_deg"])
    scale = fill_scale(cfg)          # the config's fill factor (test_fill_factor_holds_the_handbook_share_of_the_rating)
    for i in (0, len(grid) // 3, len(grid) // 2, len(grid) - 1):
        assert vol[i] == pytest.approx(scale * heaped_volume(float(grid[i]), cfg["machine"], rep), abs=1e-15)


def test_capacity_in_kg_at_the_config_density(cfg):
    """The figures the docs quote (printed with -s)."""
    mc = cfg["machine"]
    rep = r(cfg["task"]["bucket_repose_deg"])
    rho = 0.5 * (cfg["pile"]["density_min"] + cfg["pile"]["density_max"])
    vs = struck_volume(mc)
    level = bucket_section(mc)["level_strike_pitch"]
    rows = {"struck": vs, "SAE heaped (2:1, level)": sae_heaped_volume(mc),
            "attack pose": heaped_volume(0.0, mc, rep), "40 deg curl": heaped_volume(r(40.0), mc, rep),
            "level strike": heaped_volume(level, mc, rep)}
    for name, v in rows.items():
        print(f"{name:>24}: {v * 1e3:6.2f} L  {v * rho:5.1f} kg at {rho:.0f} kg/m^3")
    # the paper's 30 kg rating lies between struck and heaped at gravel density
    assert vs * cfg["pile"]["density_max"] < 30.0 * 1.05
    assert rows["SAE heaped (2:1, level)"] * cfg["pile"]["density_min"] > 30.0


def _with_fill(cfg, fill):
    c = copy.deepcopy(cfg)
    c["task"]["bucket_fill_factor"] = fill
    return c


def test_fill_factor_holds_the_handbook_share_of_the_rating(cfg):
    """task.bucket_fill_factor f: with the strike plane level the table holds f x the SAE heaped rating, the
    rating written out here (struck prism + hip roof at 2:1 over the strike plane, A = hypot(plate, back),
    A <= W), and every pitch is scaled alike (the static heap's shape kept)."""
    a = math.hypot(PLATE, BACK)
    sae = 0.5 * PLATE * BACK * W + hip_roof(a, W, 0.5)               # 19.96 L
    assert sae * 1e3 == pytest.approx(19.96, abs=0.01)
    base_grid, base = capacity_table(_with_fill(cfg, 0.0))
    level = math.atan2(BACK, PLATE)
    for f in (0.76, 0.85, 0.875, 0.90, 1.0, 1.09):
        grid, vol = capacity_table(_with_fill(cfg, f))
        assert np.array_equal(grid, base_grid)
        ratio = vol / np.where(base > 0, base, np.nan)
        ok = base > 1e-9
        assert np.allclose(ratio[ok], ratio[ok][0], rtol=1e-12)       # one factor at every pitch
        # at the rating's pose, by interpolation as the simulator reads it
        assert float(np.interp(level, grid, vol)) == pytest.approx(f * sae, rel=2e-3)
    # the static heap keeps 1.10 of the rating there: f = 0.875 takes 0.875 / 1.10 of it
    static = heaped_volume(level, cfg["machine"], r(cfg["task"]["bucket_repose_deg"]))
    assert static / sae == pytest.approx(1.10, abs=0.005)
    assert fill_scale(_with_fill(cfg, 0.875)) == pytest.approx(0.875 * sae / static, rel=1e-9)


def test_no_fill_factor_is_the_static_heap(cfg):
    """0, or a file without the key (every file before 2026-12-02), is the whole static heap, bit for bit."""
    no_key = copy.deepcopy(cfg)
    no_key["task"].pop("bucket_fill_factor", None)
    g0, v0 = capacity_table(_with_fill(cfg, 0.0))
    g1, v1 = capacity_table(no_key)
    assert fill_scale(no_key) == fill_scale(_with_fill(cfg, 0.0)) == 1.0
    assert np.array_equal(g0, g1) and np.array_equal(v0, v1)
    rep = r(cfg["task"]["bucket_repose_deg"])
    assert v0[len(g0) // 2] == pytest.approx(heaped_volume(float(g0[len(g0) // 2]), cfg["machine"], rep), abs=1e-15)


def test_fill_factor_out_of_range_is_refused(cfg):
    for bad in (-0.1, 1.3):
        with pytest.raises(ConfigError, match=r"'task\.bucket_fill_factor' = .* is out of range"):
            validate(_with_fill(cfg, bad))
        with pytest.raises(ValueError, match="bucket_fill_factor"):
            fill_scale(_with_fill(cfg, bad))
    with pytest.raises(ValueError, match="bucket_fill_factor"):
        fill_scale(_with_fill(cfg, float("nan")))
    with pytest.raises(ConfigError, match="bucket_fill_factor"):
        validate(_with_fill(cfg, float("nan")))
    # inside the schema's [0, 1.2] but outside this bucket's physical range: below its struck volume (0.749 of the
    # rating, 14.96 / 19.96 L) or above its static heap (1.100)
    struck_share = 0.5 * PLATE * BACK * W / (0.5 * PLATE * BACK * W + hip_roof(math.hypot(PLATE, BACK), W, 0.5))
    assert struck_share == pytest.approx(0.749, abs=0.001)
    for bad in (0.6, 0.74, 1.11, 1.2):
        with pytest.raises(ValueError, match=r"struck and 1\.1\d\d with the static heap"):
            fill_scale(_with_fill(cfg, bad))
        with pytest.raises(ConfigError, match=r"relation violated: task\.bucket_fill_factor is 0 \(none\) or within"):
            validate(_with_fill(cfg, bad))          # refused when the file is read, with what is expected
    for good in (0.0, 0.76, 0.875, 1.09):
        assert validate(_with_fill(cfg, good))["task"]["bucket_fill_factor"] == good
