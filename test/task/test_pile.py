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


def test_pile_depth():
    assert pile_depth(r(15), 0.68) == pytest.approx(2.5378, abs=1e-3)
