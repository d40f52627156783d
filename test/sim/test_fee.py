"""The FEE (face frame, fee.py): on flat ground the closed form against an independent wedge
equilibrium (McKyes/Reece), limiting cases, monotonicity and the failure-angle search. The
sloped face is tested in test_fee_face.py."""
import math

import numpy as np
import pytest

from lhd_sim_node.fee import G, face_rake, fee_force, fee_min, n_factors, tool_force_components

r = math.radians


def wedge_equilibrium_force(beta, d, w, gamma, c, q, rho, delta, phi, c_a=0.0):
    """Solve the force balance of the passive wedge on flat ground (alpha = 0) bounded by the
    tool face, the failure plane at beta and the surface (McKyes: top length d (cot beta +
    cot rho)), as a 2x2 linear system in the unknown tool force P and failure-plane reaction R."""
    top = d / math.tan(beta) + d / math.tan(rho)            # wedge top: ahead of and above the blade
    W = gamma * G * w * d * top / 2.0                       # wedge weight
    Q = q * w * top                                         # surcharge on the wedge's top
    C = c * w * d / math.sin(beta)                          # cohesion along the failure plane
    A_ = c_a * w * d / math.sin(rho)                        # adhesion along the tool face
    b_dir = np.array([-math.cos(rho), math.sin(rho)])      # tool face, from the tip upwards
    t = np.array([math.cos(beta), math.sin(beta)])         # failure plane, up the slope
    n = np.array([-math.sin(beta), math.cos(beta)])        # its normal into the wedge
    r_dir = math.cos(phi) * n - math.sin(phi) * t          # reaction: friction opposes the wedge sliding up
    p_dir = np.array([math.sin(rho + delta), math.cos(rho + delta)])  # tool on soil, delta from the face normal
    A = np.column_stack([p_dir, r_dir])
    # P p + R r - C t - A b - (W + Q) e_z = 0 (cohesion and adhesion oppose the wedge sliding up)
    b = C * t + A_ * b_dir + np.array([0.0, W + Q])
    P, R = np.linalg.solve(A, b)
    assert R > 0
    return P


@pytest.mark.parametrize("seed", range(20))
def test_flat_ground_closed_form_equals_wedge_equilibrium(seed):
    rng = np.random.default_rng(seed)
    while True:  # admissible wedges only: D > 0 (the tool force is finite and compressive)
        phi = r(rng.uniform(25, 45))
        delta = r(rng.uniform(10, 30))
        rho = r(rng.uniform(60, 100))
        beta = r(rng.uniform(10, 40))
        if n_factors(beta, 0.0, rho, delta, phi)[4] > 0.1:
            break
    d, w = rng.uniform(0.05, 0.4), rng.uniform(0.05, 0.5)
    gamma, c, q, c_a = rng.uniform(1500, 2200), rng.uniform(0, 500), rng.uniform(0, 2000), rng.uniform(0, 300)
    F = fee_force(beta, d, w, gamma, c, q, c_a, 0.0, rho, delta, phi)
    assert F == pytest.approx(wedge_equilibrium_force(beta, d, w, gamma, c, q, rho, delta, phi, c_a), rel=1e-9)


def test_limiting_cases_of_the_n_factors():
    beta, rho, delta, phi = r(30), r(70), r(20), r(35)
    ng, nc, nq, na, D = n_factors(beta, 0.0, rho, delta, phi)
    # D by hand, and at alpha = 0 the slope term is 1
    assert D == pytest.approx(math.cos(r(90)) + math.sin(r(90)) / math.tan(r(65)))
    assert nq == pytest.approx(2.0 * ng)  # weight and surcharge act on the same wedge top
    assert ng == pytest.approx((1.0 / math.tan(beta) + 1.0 / math.tan(rho)) / (2.0 * D))
    assert nc == pytest.approx((1.0 + 1.0 / (math.tan(beta) * math.tan(beta + phi))) / D)
    # on a face the surcharge factor does not see the slope, the weight factor leans with it
    alpha = r(25)
    ng_a, _, nq_a, _, _ = n_factors(beta, alpha, rho, delta, phi)
    assert nq_a == pytest.approx(nq)
    assert ng_a == pytest.approx(nq * (math.cos(alpha) + math.sin(alpha) / math.tan(beta + phi)) / 2.0)
    # a smooth vertical tool on flat ground: D = cot(beta + phi), N_q = cot(beta) tan(beta + phi)
    _, _, nq_s, na_s, D_s = n_factors(beta, 0.0, r(90), 0.0, phi)
    assert D_s == pytest.approx(1.0 / math.tan(beta + phi))
    assert nq_s == pytest.approx(math.tan(beta + phi) / math.tan(beta))
    assert na_s == pytest.approx(math.tan(beta + phi))  # cot(90 deg) = 0: N_a = 1 / D
    # no soil weight, cohesion or surcharge: no force
    assert fee_force(beta, 0.2, 0.4, 0.0, 0.0, 0.0, 0.0, alpha, rho, delta, phi) == 0.0


def test_failure_angle_minimises_the_force():
    args = dict(w=0.4, gamma=1850.0, c=50.0, q=600.0, c_a=0.0, alpha=r(20), rho=r(60), delta=r(25), phi=r(38))
    F, beta = fee_min(np.array([0.2]), **args)
    fine = np.radians(np.linspace(1, 89, 20001))
    vals = fee_force(fine, 0.2, args["w"], args["gamma"], args["c"], args["q"], args["c_a"], args["alpha"],
                     args["rho"], args["delta"], args["phi"])
    ng, nc, nq, na, D = n_factors(fine, args["alpha"], args["rho"], args["delta"], args["phi"])
    ok = D > 0
    best = vals[ok].min()
    assert F[0] == pytest.approx(best, rel=2e-3)
    assert F[0] >= best * (1 - 1e-12)
    assert r(1) <= beta[0] <= r(89)


def test_force_grows_with_depth_and_with_slope():
    kw = dict(w=0.4, gamma=1850.0, c=0.0, q=500.0, c_a=0.0, rho=r(60), delta=r(25), phi=r(38))
    depths = np.linspace(0.02, 0.4, 20)
    F, _ = fee_min(depths, alpha=r(20), **kw)
    assert np.all(np.diff(F) > 0)
    # at a fixed penetration x into the pile the tool is deeper on a steeper pile: d = x tan(alpha)
    # vertically, x sin(alpha) normal to the face, where the blade stands at 60 deg + alpha
    x = 0.5
    kw.pop("rho")
    forces = [fee_min(np.array([x * math.sin(r(a))]), alpha=r(a), rho=face_rake(r(60), r(a), kw["delta"], kw["phi"], r(30)),
                      **kw)[0][0] for a in (15, 20, 25, 30)]
    assert np.all(np.diff(forces) > 0)
    assert fee_min(np.array([0.0, -0.1]), alpha=r(20), rho=r(80), **kw)[0].tolist() == [0.0, 0.0]


def test_force_components():
    h, v = tool_force_components(100.0, r(60), r(25))
    assert h == pytest.approx(100 * math.sin(r(85)))
    assert v == pytest.approx(100 * math.cos(r(85)))
