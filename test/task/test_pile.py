"""The voxel pile: geometry, masses against the closed-form wedge, cutting, rocks."""
import math

import numpy as np
import pytest

from lhd_loading_ros.task.pile import SoilRanges, VoxelPile, pile_depth, wedge_mass_until

r = math.radians


def uniform_pile(alpha_deg=20.0, rho=1800.0, n=(60, 7, 10)):
    shape = (n[1], n[0], n[2])
    return VoxelPile(r(alpha_deg), 0.68, 0.4, n[0], n[1], n[2], np.full(shape, rho), np.full(shape, r(38)),
                     np.full(shape, r(25)), np.zeros(shape), 0.0, 500.0)


def test_geometry_of_the_wedge():
    p = uniform_pile(30.0)
    assert p.L == pytest.approx(0.68 / math.tan(r(30)))
    assert (p.dx, p.dy, p.dz) == pytest.approx((p.L / 60, 0.4 / 7, 0.068))
    # a wedge fills about half its bounding box: the paper's ~2,100 of 4,200 voxels
    assert 2000 <= p.voxel_count() <= 2400  # voxels cut by the face count as holding material
    assert p.surface_height(-0.1) == 0.0 and p.surface_height(p.L + 0.1) == 0.68
    assert p.surface_height(0.5) == pytest.approx((math.floor(0.5 / p.dx) + 0.5) * p.dx * math.tan(r(30)))


@pytest.mark.parametrize("alpha", [15.0, 22.0, 30.0])
def test_masses_match_the_closed_form_wedge(alpha):
    p = uniform_pile(alpha)
    exact = wedge_mass_until(p.L, r(alpha), 0.4, 1800.0, 0.68)
    assert p.total_mass() == pytest.approx(exact, rel=0.01)
    for m in (65.0, 170.0):
        x = p.x_at_mass(m)
        assert x == pytest.approx(math.sqrt(2 * m / (1800.0 * 0.4 * math.tan(r(alpha)))), rel=0.01)
    assert p.x_at_mass(1e6) == p.L


def test_cut_removes_the_material_above_the_trajectory():
    p = uniform_pile(20.0)
    j = np.arange(p.n_y)
    before = p.total_mass()
    # a floor-level pass from the toe to x = 0.5 removes the wedge up to the last passed centre
    m = p.cut(-0.05, 0.0, 0.5, 0.0, j)
    last_centre = (math.floor(0.5 / p.dx - 0.5) + 1) * p.dx  # right edge of the last cut column
    assert m == pytest.approx(wedge_mass_until(last_centre, r(20), 0.4, 1800.0, 0.68), rel=0.02)
    assert p.total_mass() == pytest.approx(before - m)
    assert p.removed_mass == pytest.approx(m)
    # a second pass higher up removes nothing; going back removes nothing
    assert p.cut(0.0, 0.1, 0.5, 0.1, j) == 0.0
    assert p.cut(0.5, 0.0, 0.4, 0.0, j) == 0.0
    fills = p.fills()
    assert fills.min() >= 0.0 and fills.max() <= 1.0
    # the surface behind the tip is now the floor
    assert p.surface_height(0.3) == 0.0


def test_cut_only_touches_the_given_slices():
    p = uniform_pile(20.0)
    m = p.cut(0.0, 0.0, 0.5, 0.0, np.array([3]))
    assert m > 0
    assert p.top[3, 5] == 0.0 and p.top[2, 5] > 0.0


def test_generated_piles_rocks_and_per_voxel_parameters(cfg):
    soil = SoilRanges.from_config(cfg)
    rng = np.random.default_rng(3)
    homo = VoxelPile.generate(rng, r(25), 0.68, 0.4, 60, 7, 10, soil)
    assert homo.klass.sum() == 0
    assert soil.density[0] * 0.95 <= homo.density.min() and homo.density.max() <= soil.density[1] * 1.05
    assert homo.density.std() > 0  # each voxel its own
    assert soil.surcharge[0] <= homo.surcharge <= soil.surcharge[1]
    rocky = VoxelPile.generate(np.random.default_rng(3), r(25), 0.68, 0.4, 60, 7, 10, soil, nonhomogeneous=True)
    assert soil.rocks[0] <= rocky.rocks <= soil.rocks[1]
    assert rocky.klass.sum() > 0
    assert np.all(rocky.density[rocky.klass == 1] == soil.rock_density)
    assert rocky.total_mass() > homo.total_mass()
    with pytest.raises(ValueError, match="density must have shape"):
        VoxelPile(r(20), 0.68, 0.4, 60, 7, 10, np.zeros((1, 2, 3)), np.zeros((7, 60, 10)), np.zeros((7, 60, 10)),
                  np.zeros((7, 60, 10)), 0.0, 0.0)


def test_no_pile_stands_steeper_than_its_friction_angle(cfg):
    """A cohesionless face stands at most at its friction angle: each pile's gravel draws phi from
    [max(phi_min, alpha), phi_max]; a slope above phi_max is refused, naming both angles."""
    from dataclasses import replace
    soil = replace(SoilRanges.from_config(cfg), phi=(r(34.0), r(45.0)))
    gravel = lambda p: math.degrees(float(p.phi[p.klass == 0].flat[0]))  # noqa: E731
    for alpha, lo in ((20.0, 34.0), (34.0, 34.0), (40.0, 40.0), (44.0, 44.0), (45.0, 45.0)):
        drawn = [gravel(VoxelPile.generate(np.random.default_rng(s), r(alpha), 0.68, 0.4, 30, 3, 5, soil))
                 for s in range(40)]
        assert min(drawn) >= lo - 1e-9 and max(drawn) <= 45.0 + 1e-9
        if alpha < 44.0:  # a draw, not a constant: spread over the allowed interval
            assert max(drawn) - min(drawn) > 0.5 * (45.0 - lo)
    # the same generator state gives the same pile below phi_min (shallow piles unchanged by the rule)
    a = VoxelPile.generate(np.random.default_rng(7), r(20), 0.68, 0.4, 30, 3, 5, soil)
    rng = np.random.default_rng(7)
    rng.uniform(*soil.density)
    assert gravel(a) == pytest.approx(math.degrees(rng.uniform(r(34.0), r(45.0))))
    with pytest.raises(ValueError, match=r"a pile of 46.0 deg is steeper than its material's largest friction "
                                         r"angle \(45.0 deg\)"):
        VoxelPile.generate(np.random.default_rng(0), r(46.0), 0.68, 0.4, 30, 3, 5, soil)


def test_a_config_whose_randomised_material_cannot_stand_at_its_steepest_slope_is_refused(cfg):
    import copy
    from lhd_loading_ros.task.config import validate
    c = copy.deepcopy(cfg)
    c["paper"]["episode"]["alpha_max_deg"] = 36.0
    c["pile"]["phi_max_deg"] = 40.0
    c["randomization"]["phi_max_deg"] = 35.0
    with pytest.raises(ValueError, match=r"alpha_max_deg <= randomization.phi_max_deg"):
        validate(c)
    c["randomization"]["phi_max_deg"] = 41.0
    validate(c)


def test_pile_depth():
    assert pile_depth(r(15), 0.68) == pytest.approx(2.5378, abs=1e-3)


def test_a_rough_surface_has_the_relief_it_was_asked_for():
    """VoxelPile.roughen: a Gaussian random field about the plane. Checked over 300 piles against
    the field's own definition, not the code's steps: mean 0, sd as asked (up to the few columns the
    clip to [0, h] touches), and the autocorrelation of a field smoothed by a Gaussian of sd corr/2
    per axis, exp(-r^2 / corr^2): e^-1 at r = corr (here 5 columns of 3.11 cm, 0.156 m: 0.34)."""
    sd, corr = 0.03, 0.15
    d_all, pairs0, pairs5 = [], [], []
    for seed in range(300):
        p = uniform_pile(20.0)
        plane = p.top0.copy()
        p.roughen(np.random.default_rng(seed), sd, corr)
        assert np.array_equal(p.top, p.top0) and p.top is not p.top0
        assert p.top0.min() >= 0.0 and p.top0.max() <= p.h
        d = p.top0 - plane
        inner = (plane > 3 * sd) & (plane < p.h - 3 * sd)            # where the clip cannot act
        d_all.append(d[inner])
        pairs0.append(d[:, 10:40].ravel())
        pairs5.append((d[:, 10:40] * d[:, 15:45]).ravel())
    d_all = np.concatenate(d_all)
    assert abs(d_all.mean()) < 0.002 and d_all.std() == pytest.approx(sd, rel=0.08)
    rho5 = np.concatenate(pairs5).mean() / np.concatenate(pairs0).var()
    lag = 5 * p.dx
    assert rho5 == pytest.approx(math.exp(-(lag / corr) ** 2), abs=0.06)
    # the masses and zones follow the new surface: the intact pile's mass is that of its fills
    q = uniform_pile(20.0)
    m_plane = q.total_mass()
    x_plane = q.x_at_mass(65.0)
    q.roughen(np.random.default_rng(7), 0.05, corr)
    col = np.sum(np.clip((q.top0[:, :, None] - q.z_edges[None, None, :-1]) / q.dz, 0, 1) * q._voxel_mass)
    assert q.total_mass() == pytest.approx(col) and q.total_mass() != pytest.approx(m_plane, rel=1e-4)
    assert q.x_at_mass(65.0) != pytest.approx(x_plane, abs=1e-6)
    # sd 0: the plane, and nothing drawn; bad values are refused naming them
    z = uniform_pile(20.0)
    g = np.random.default_rng(3)
    before = g.bit_generator.state
    z.roughen(g, 0.0, corr)
    assert np.array_equal(z.top0, uniform_pile(20.0).top0) and g.bit_generator.state == before
    for bad in ((-0.01, corr), (float("nan"), corr), (0.03, 0.0)):
        with pytest.raises(ValueError, match="surface relief needs sd >= 0 and corr > 0"):
            z.roughen(g, *bad)


def test_validate_physics_leaves_out_a_wedge_steeper_than_the_files_gravel(cfg):
    """`lhd validate physics` builds its homogeneous piles at the midpoint friction angle: a file whose
    gravel (31-37 deg, midpoint 34) is weaker than the 35 deg wedge leaves that slope out instead of
    failing on a pile that cannot stand (a review, 2026-11-29)."""
    import copy

    from lhd_sim_node.validate import resistance_vs_slope
    c = copy.deepcopy(cfg)
    c["pile"]["phi_min_deg"], c["pile"]["phi_max_deg"] = 31.0, 37.0
    rows = resistance_vs_slope(c, slopes=(30.0, 35.0), flat=False)
    assert [r["slope_deg"] for r in rows["equal_insertion"]] == [30.0]
    assert [r["slope_deg"] for r in rows["fixed_depth"]] == [30.0]
