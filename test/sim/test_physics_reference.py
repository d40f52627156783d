"""The independent references of issue 13 (lhd_sim_node/reference_mechanics.py) against numbers
computed by hand (written out literally here) and textbook closed forms: the passive wedge,
the breakout of a buried bucket and the bucket's heaped capacity. Fast: no simulator."""
import ast
import math
from pathlib import Path

import numpy as np
import pytest

from reference_mechanics import (GRAVEL_DENSITY, BucketGeometry, Soil, breakout, bucket_capacity_at_pitch,
                                 bucket_capacity_iso7546, face_frame, passive_wedge, pile_surface, rating_density,
                                 wedge_at)

r = math.radians
# The soil the issue's figures imply: the midpoints of the shipped pile ranges at the time of the
# issue (density 3,100-3,400 kg/m^3, phi 35-42 deg, delta 22-28 deg, c 0-200 Pa, q 250-1,000 Pa,
# adhesion 0), blade = the bucket's effective rake of 60 deg in the attack pose, 0.40 m wide.
ISSUE_SOIL = Soil(gamma=3250.0, phi=r(38.5), delta=r(25.0), c=100.0, c_a=0.0, q=625.0)
W = 0.40
TIP_Z = 0.015   # the tip's height above the floor in the attack pose (plate 10 mm over a 5 mm gap)
MACHINE = {"bucket_tip_ahead_of_hinge": 0.30, "bucket_hinge_height": 0.12, "bucket_back_height": 0.26,
           "bucket_width": 0.40}


def coulomb_passive_force(d, w, gamma, phi, delta, i):
    """Coulomb's passive force on a vertical wall of height d behind a backfill rising at i, wall
    friction delta (Das, Principles of Foundation Engineering, Coulomb's passive pressure, wall
    angle 0): P = gamma g d^2 w Kp / 2,
    Kp = cos^2 phi / (cos delta (1 - sqrt(sin(phi+delta) sin(phi+i) / (cos delta cos i)))^2)."""
    kp = math.cos(phi) ** 2 / (math.cos(delta) * (1 - math.sqrt(math.sin(phi + delta) * math.sin(phi + i) /
                                                                 (math.cos(delta) * math.cos(i)))) ** 2)
    return 0.5 * gamma * 9.81 * d * d * w * kp


def closed_form_force(beta, d, w, s: Soil, alpha, rho):
    """The same wedge balance derived on paper the other way: project the balance on the direction
    normal to the failure-plane reaction (angle beta + phi), which removes R:
    P sin(rho+delta+beta+phi) = W sin(beta+phi) + Q sin(beta+phi-alpha) + C cos(phi) - A cos(rho+beta+phi)
    with the triangle from the law of sines: TB = d cos(a)/sin(rho+a), TF = d cos(a)/sin(beta-a),
    BF = d cos(a) sin(rho+beta)/(sin(rho+a) sin(beta-a)), area = BF d cos(a) / 2."""
    ca = math.cos(alpha)
    bf = d * ca * math.sin(rho + beta) / (math.sin(rho + alpha) * math.sin(beta - alpha))
    Wt = s.gamma * 9.81 * w * 0.5 * bf * d * ca
    Q, C, A = s.q * w * bf, s.c * w * d * ca / math.sin(beta - alpha), s.c_a * w * d * ca / math.sin(rho + alpha)
    ph = s.phi
    return (Wt * math.sin(beta + ph) + Q * math.sin(beta + ph - alpha) + C * math.cos(ph)
            - A * math.cos(rho + beta + ph)) / math.sin(rho + s.delta + beta + ph)


def test_rankine_bell_passive_force_on_flat_ground():
    """Smooth vertical blade, flat ground: the wedge is Rankine's with Bell's cohesion term,
    P = w (gamma g d^2 Kp / 2 + 2 c d sqrt(Kp) + q d Kp), Kp = tan^2(45 + phi/2) = 3 at phi = 30 deg:
    0.4 (0.5 * 2000 * 9.81 * 0.04 * 3 + 2 * 500 * 0.2 * 1.7320508 + 1000 * 0.2 * 3)
    = 0.4 (1177.2 + 346.41016 + 600) = 849.4441 N, failure plane at 45 - phi/2 = 30 deg."""
    res = passive_wedge(0.2, 0.4, Soil(2000.0, r(30), 0.0, c=500.0, q=1000.0), 0.0, r(90))
    assert res.P == pytest.approx(849.4441, rel=1e-5)
    assert math.degrees(res.beta) == pytest.approx(30.0, abs=0.01)
    assert res.vertical == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("phi, delta, i, hand", [(35, 20, 15, 3946.0), (40, 10, 30, 14154.0)])
def test_coulomb_passive_force_on_a_sloped_backfill(phi, delta, i, hand):
    """Vertical rough wall, backfill rising at i: Coulomb's Kp by hand (35/20/15 deg: 25.140,
    P = 0.5 * 2000 * 9.81 * 0.04 * 0.4 * 25.140 = 3946 N; 40/10/30 deg: Kp = 90.18, 14154 N)."""
    ref = coulomb_passive_force(0.2, 0.4, 2000.0, r(phi), r(delta), r(i))
    assert ref == pytest.approx(hand, rel=2e-4)
    res = passive_wedge(0.2, 0.4, Soil(2000.0, r(phi), r(delta)), r(i), r(90))
    assert res.P == pytest.approx(hand, rel=2e-4)
    assert res.horizontal == pytest.approx(hand * math.cos(r(delta)), rel=2e-4)


@pytest.mark.parametrize("seed", range(12))
def test_vector_balance_equals_the_closed_form_at_any_failure_angle(seed):
    rng = np.random.default_rng(seed)
    alpha = r(rng.choice([0.0, 15.0, 30.0, 35.0]))
    s = Soil(rng.uniform(1500, 3400), r(rng.uniform(30, 45)), r(rng.uniform(10, 30)), rng.uniform(0, 300),
             rng.uniform(0, 100), rng.uniform(0, 1500))
    rho = r(rng.uniform(40, 90))
    d = rng.uniform(0.03, 0.3)
    n = 0
    for beta in np.radians(np.linspace(math.degrees(alpha) + 2, 178 - math.degrees(rho), 80)):
        res = wedge_at(float(beta), d, 0.4, s, alpha, rho)
        if res is None:
            continue
        n += 1
        assert res.P == pytest.approx(closed_form_force(float(beta), d, 0.4, s, alpha, rho), rel=1e-9)
    assert n >= 5


def test_a_wedge_by_hand_at_a_fixed_failure_angle():
    """30 deg face, beta = 50 deg, rake 60 deg, d = 0.1 m, the issue's soil, by hand:
    TB = 0.1 cos30 / sin90 = 0.086603, TF = 0.1 cos30 / sin20 = 0.253209,
    BF = 0.086603 sin110 / sin20 = 0.237940, area = BF * 0.1 cos30 / 2 = 0.0103030 m^2,
    W = 3250 * 9.81 * 0.4 * 0.0103030 = 131.39 N, Q = 625 * 0.4 * BF = 59.485 N,
    C = 100 * 0.4 * TF = 10.128 N; P = (W sin88.5 + Q sin58.5 + C cos38.5) / sin173.5
    = (131.35 + 50.72 + 7.93) / 0.113203 = 1678.4 N."""
    res = wedge_at(r(50), 0.1, W, ISSUE_SOIL, r(30), r(60))
    assert res.area == pytest.approx(0.0103030, rel=1e-4)
    assert res.weight == pytest.approx(131.39, rel=1e-3)
    assert res.P == pytest.approx(1678.4, rel=1e-3)


def test_the_issues_fixed_depth_figures():
    """Issue 13: at 0.10 m (vertical) depth the Coulomb wedge rises from 426 N (flat) to 1,680 N
    (35 deg); horizontal components with the issue's soil and a 60 deg blade. Hand-checked values
    (the issue's own independent calculation) for 0/15/30/35 deg, with cohesion and surcharge."""
    hand = {0: 426.3, 15: 660.2, 30: 1238.8, 35: 1680.3}
    got = {a: passive_wedge(0.10, W, ISSUE_SOIL, r(a), r(60)).horizontal for a in hand}
    for a, v in hand.items():
        assert got[a] == pytest.approx(v, rel=2e-3), a
    assert got[0] == pytest.approx(426.0, abs=1.0) and got[35] == pytest.approx(1680.0, abs=1.0)


def test_the_issues_equal_insertion_figures():
    """Issue 13: the tip 0.25 m (horizontally) into 15/20/25/30 deg piles, 15 mm above the floor:
    depth 0.25 tan(alpha) - 0.015; the wedge balance gives 227/498/996/1,934 N."""
    got = [passive_wedge(0.25 * math.tan(r(a)) - TIP_Z, W, ISSUE_SOIL, r(a), r(60)).horizontal for a in (15, 20, 25, 30)]
    assert got == pytest.approx([227.0, 498.0, 996.0, 1934.0], abs=1.0)
    assert np.all(np.diff(got) > 0)


def test_the_minimum_is_the_least_force_over_failure_angles():
    res = passive_wedge(0.12, W, ISSUE_SOIL, r(25), r(60))
    fine = [wedge_at(float(b), 0.12, W, ISSUE_SOIL, r(25), r(60)) for b in np.radians(np.linspace(25.01, 119.9, 20000))]
    best = min(f.P for f in fine if f is not None)
    assert res.P <= best * (1 + 1e-9) and res.P == pytest.approx(best, rel=1e-5)


def test_face_frame_conversion():
    dn, rho_f = face_frame(0.1, r(60), r(30))
    assert dn == pytest.approx(0.1 * math.cos(r(30))) and rho_f == pytest.approx(r(90))


def test_breakout_by_hand():
    """Bucket floor horizontal 15 mm above the floor, hinge at x = 0 (lip at 0.30 m) in a 20 deg
    pile, the issue's soil, K0 = 1 - sin 38.5 = 0.37749 (K0 tan phi = 0.30027). Column over the
    floor: x0 = 0.015 / tan20 = 0.04121 to 0.30, height at the lip Ht = 0.094191, area
    0.5 * 0.25879 * Ht = 0.012188 m^2: W = 3250 * 9.81 * 0.4 * 0.012188 = 155.43 N,
    Q = 625 * 0.4 * 0.25879 = 64.70 N; per side plane int c H + K0 tan(phi)(gamma g H^2 / 2 + q H)
    = 1.2188 + 0.30027 (12.200 + 7.6175) = 7.169 N, two: 14.34 N; lip plane 0.4 (9.4191 + 0.30027
    (141.43 + 58.869)) = 27.83 N. Lift 262.3 N. Curl torque about the hinge (centroids 0.21374 for
    H, 0.23530 for H^2, 0.17061 for Q, 0.30 at the lip): 33.22 + 11.04 + 1.50 + 1.72 + 8.35
    = 55.83 N m."""
    geom = BucketGeometry.from_machine(MACHINE)
    b = breakout((0.0, 0.12), 0.0, geom, pile_surface(r(20), 0.68), ISSUE_SOIL, pivot_xz=(-0.7, 0.40))
    assert b.lip_depth == pytest.approx(0.094191, rel=1e-4)
    assert b.weight == pytest.approx(155.43, rel=2e-3)
    assert b.surcharge == pytest.approx(64.70, rel=3e-3)
    assert b.shear_sides == pytest.approx(14.34, rel=3e-3)
    assert b.shear_front == pytest.approx(27.83, rel=1e-3)
    assert b.lift_force == pytest.approx(262.3, rel=2e-3)
    assert b.curl_torque == pytest.approx(55.83, rel=3e-3)
    # a rigid rotation about the pivot: the same vertical forces, levers 0.7 m longer
    assert b.boom_torque == pytest.approx(b.curl_torque + 0.7 * b.lift_force, rel=1e-9)


def test_breakout_in_air_is_zero_and_grows_with_burial():
    geom = BucketGeometry.from_machine(MACHINE)
    air = breakout((0.0, 0.12), 0.0, geom, lambda x: np.zeros_like(np.asarray(x, dtype=float)), ISSUE_SOIL)
    assert air.lift_force == 0.0 and air.curl_torque == 0.0
    lifts = [breakout((x, 0.12), 0.0, geom, pile_surface(r(20), 0.68), ISSUE_SOIL).lift_force for x in (0.0, 0.1, 0.2)]
    assert np.all(np.diff(lifts) > 0)


def test_iso7546_capacity_by_hand():
    """Inner section: 0.295 m floor (0.30 - half the 10 mm back plate), 0.26 m back, 0.39 m inner
    width. Struck 0.5 * 0.295 * 0.26 * 0.39 = 14.9565 L; strike line a = hypot(0.295, 0.26) =
    0.393224 m; ISO 7546 heap (1:2) a^2 b / 8 - a^3 / 24 = 7.5380 - 2.5334 = 5.0045 L; heaped
    19.961 L (issue: 14.96 L struck, about 20 L heaped; 28.4 kg struck at 1,900 kg/m^3)."""
    geom = BucketGeometry.from_machine(MACHINE)
    cap = bucket_capacity_iso7546(geom)
    assert cap["struck_m3"] * 1e3 == pytest.approx(14.9565, rel=1e-6)
    assert cap["heaped_m3"] * 1e3 == pytest.approx(19.961, rel=1e-4)
    assert cap["struck_m3"] * 1900 == pytest.approx(28.42, rel=1e-3)
    # the pitch-dependent section reproduces ISO where the strike line is horizontal
    assert bucket_capacity_at_pitch(geom, cap["iso_pitch_rad"], math.atan(0.5)) == pytest.approx(cap["heaped_m3"], rel=1e-5)
    # attack pose, floor level: only the repose wedge on the floor, 0.5 * 0.295^2 * 0.5 * 0.39 = 8.485 L
    assert bucket_capacity_at_pitch(geom, 0.0, math.atan(0.5)) * 1e3 == pytest.approx(8.4849, rel=1e-4)
    # a steeper repose angle heaps more
    assert bucket_capacity_at_pitch(geom, cap["iso_pitch_rad"], r(35)) > cap["heaped_m3"]


def test_the_bucket_is_rated_for_dry_gravel_and_the_pile_is_denser():
    """A loader bucket's rated payload is its heaped (SAE J742 / ISO 7546, 2:1) volume times the loose
    density of the material it is rated for. By hand: 30 kg / 19.961 L = 1,503 kg/m^3 (the struck
    14.9565 L and the heap 5.0045 L of test_iso7546_capacity_by_hand). That is dry, loose gravel
    (handbook 1,522; dry 6-50 mm 1,682), not the config's pile (1,760-2,000 kg/m^3, moist); the paper
    gives neither its bucket's dimensions nor its gravel's density (docs/modeling.md "The material the
    bucket is rated for")."""
    from lhd_loading_ros.task.config import load_config
    cfg = load_config(None)
    heaped = bucket_capacity_iso7546(BucketGeometry.from_machine(cfg["machine"]))["heaped_m3"]
    rho = rating_density(heaped, cfg["task"]["bucket_capacity"])
    assert rho == pytest.approx(30.0 / 0.019961, rel=1e-4) and rho == pytest.approx(1503.0, abs=1.0)
    assert GRAVEL_DENSITY["dry, loose"] <= rho * 1.02 and rho < GRAVEL_DENSITY["dry, 6-50 mm"]
    assert cfg["pile"]["density_min"] > GRAVEL_DENSITY["dry, 6-50 mm"]     # the departure the docs name
    assert GRAVEL_DENSITY["dry, loose"] < cfg["randomization"]["density_min"] + 100.0   # `--stress light` is it
    with pytest.raises(ValueError, match="must be > 0"):
        rating_density(0.0, 30.0)


def test_the_reference_never_imports_the_simulators_physics():
    """Independence: neither the package reference nor this test's shim imports fee, fee_kernel,
    bucket_body or the simulator."""
    here = Path(__file__).resolve()
    paths = [here.parents[2] / "lhd_sim_node" / "lhd_sim_node" / "reference_mechanics.py",
             here.parent / "reference_mechanics.py"]
    banned = ("fee", "fee_kernel", "bucket_body", "simulator")
    for p in paths:
        for n in ast.walk(ast.parse(p.read_text())):
            if isinstance(n, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in n.names] + ([n.module] if isinstance(n, ast.ImportFrom) and n.module else [])
                for name in names:
                    assert name.split(".")[-1] not in banned, f"{p.name} imports {name}"
