"""Zones.for_measured_pile (the real machine's end zone from a measured slope and toe and a
nominal density) against an independent calculation: the simulator's own zones of a freshly
generated homogeneous voxel pile of the same slope and density, a number worked by hand, and
properties; as_list / from_list, the /lhd/pile/zones message."""
import dataclasses
import math

import numpy as np
import pytest

from lhd_loading_ros.task.pile import SoilRanges, VoxelPile
from lhd_loading_ros.task.zones import Zones

r = math.radians
RHO = 3250.0          # kg/m^3: a dense ore (the config's gravel is 1,760-2,000; test_gravel_geometry.py)


def voxel_pile(cfg, alpha_deg, rho, seed=0):
    """The simulator's pile of this slope, every voxel at exactly `rho` (no per-voxel spread)."""
    soil = dataclasses.replace(SoilRanges.from_config(cfg), density=(rho, rho))
    v = cfg["paper"]["voxels"]
    e = cfg["paper"]["episode"]
    return VoxelPile.generate(np.random.default_rng(seed), r(alpha_deg), e["h_pile"], e["w_pile"], v["n_x"], v["n_y"],
                              v["n_z"], soil, nonhomogeneous=False, voxel_spread=0.0)


@pytest.mark.parametrize("alpha", [15.0, 20.0, 25.0, 30.0])
def test_same_zones_as_the_simulators_voxel_pile(cfg, params, alpha):
    pile = voxel_pile(cfg, alpha, RHO, seed=int(alpha))
    sim = Zones.for_pile(pile, params)
    meas = Zones.for_measured_pile(r(alpha), 0.0, RHO, params)
    # the voxel pile integrates the wedge column by column (exact for the linear face) and
    # interpolates its cumulative mass linearly between column edges: the end zone within one
    # voxel, in fact within a tenth of one (a density off by 8 %, 3000 for 3250, moves x_max
    # by 0.027-0.040 m, 1.4-1.0 voxels)
    assert abs(meas.x_min - sim.x_min) < pile.dx / 10, (meas, sim, pile.dx)
    assert abs(meas.x_max - sim.x_max) < pile.dx / 10, (meas, sim, pile.dx)
    # the rest is the same geometry: back end L = h / tan(alpha) minus d_cutoff, observation zone
    assert meas.x_cutoff == pytest.approx(sim.x_cutoff, abs=1e-9)
    assert (meas.z_min, meas.x_obs_start, meas.x_obs_end, meas.y_half, meas.z_top) == pytest.approx(
        (sim.z_min, sim.x_obs_start, sim.x_obs_end, sim.y_half, sim.z_top))
    # and the end zone lies inside the pile, before the restricted cut
    assert 0.0 < meas.x_min < meas.x_max < meas.x_cutoff


def test_hand_computed_20_deg(paper_params):
    params = paper_params
    # tan 20 deg = 0.363970; rho w tan = 3250 * 0.4 * 0.363970 = 473.161 kg/m^2 per m
    # x_min = sqrt(2 * 65 / 473.161) = sqrt(0.274748) = 0.524164 m
    # x_max = sqrt(2 * 170 / 473.161) = sqrt(0.718571) = 0.847686 m
    # L = 0.68 / 0.363970 = 1.868285 m; x_cutoff = L - 0.1 = 1.768285 m
    z = Zones.for_measured_pile(r(20.0), 0.0, 3250.0, params)
    assert z.as_list() == pytest.approx([0.524164, 0.847686, 0.35, 1.768285, -0.1, 1.0, 0.2, 0.4], abs=2e-6)
    # the toe 0.12 m farther: every x limit 0.12 m farther, the heights and the width unchanged
    s = Zones.for_measured_pile(r(20.0), 0.12, 3250.0, params)
    assert s.as_list() == pytest.approx([0.644164, 0.967686, 0.35, 1.888285, 0.02, 1.12, 0.2, 0.4], abs=2e-6)


def test_lighter_material_pushes_the_end_zone_deeper(params):
    dens = [5000.0, 4000.0, 3400.0, 3250.0, 3100.0, 2500.0, 1800.0]
    zs = [Zones.for_measured_pile(r(22.0), 0.0, d, params) for d in dens]
    for a, b in zip(zs, zs[1:]):
        assert b.x_min > a.x_min and b.x_max > a.x_max
        assert b.x_cutoff == a.x_cutoff          # the pile's depth does not depend on its density
    # x scales as 1 / sqrt(density)
    assert zs[-1].x_max / zs[0].x_max == pytest.approx(math.sqrt(5000.0 / 1800.0))


def test_toe_shift_moves_everything_along_x(params):
    base = Zones.for_measured_pile(r(27.0), 0.0, RHO, params)
    for shift in (-0.4, -0.05, 0.03, 0.5):
        z = Zones.for_measured_pile(r(27.0), shift, RHO, params)
        for name in ("x_min", "x_max", "x_cutoff", "x_obs_start", "x_obs_end"):
            assert getattr(z, name) == pytest.approx(getattr(base, name) + shift)
        assert (z.z_min, z.y_half, z.z_top) == (base.z_min, base.y_half, base.z_top)


def test_steeper_piles_bring_the_end_zone_closer(params):
    xs = [Zones.for_measured_pile(r(a), 0.0, RHO, params).x_max for a in (10, 15, 20, 25, 30, 40, 50)]
    assert all(b < a for a, b in zip(xs, xs[1:]))


def test_capped_at_the_back_end_of_a_light_pile(params):
    # 45 deg, 1000 kg/m^3: the wedge holds 1000 * 0.4 * 0.68^2 / 2 = 92.5 kg < m_max = 170 kg
    z = Zones.for_measured_pile(r(45.0), 0.1, 1000.0, params)
    L = 0.68 / math.tan(r(45.0))
    assert z.x_max == pytest.approx(0.1 + L)
    assert z.x_min == pytest.approx(0.1 + math.sqrt(2 * 65.0 / (1000.0 * 0.4 * 1.0)))


@pytest.mark.parametrize("alpha, toe, rho, what", [
    (math.nan, 0.0, RHO, "pile slope"), (0.0, 0.0, RHO, "pile slope"), (math.pi / 2, 0.0, RHO, "pile slope"),
    (-0.3, 0.0, RHO, "pile slope"), (0.3, math.inf, RHO, "pile toe"), (0.3, 0.0, 0.0, "bulk density"),
    (0.3, 0.0, math.nan, "bulk density"),
])
def test_bad_measurements_are_refused_with_the_value(params, alpha, toe, rho, what):
    with pytest.raises(ValueError, match=what):
        Zones.for_measured_pile(alpha, toe, rho, params)


def test_as_list_from_list_round_trip_and_validation(params):
    z = Zones.for_measured_pile(r(18.0), 0.07, RHO, params)
    assert Zones.from_list(z.as_list()) == z
    assert Zones.from_list(np.array(z.as_list())) == z
    vals = z.as_list()
    with pytest.raises(ValueError, match="expected 8 values"):
        Zones.from_list(vals[:3])
    with pytest.raises(ValueError, match="x_max not finite"):
        Zones.from_list(vals[:1] + [math.nan] + vals[2:])
    with pytest.raises(ValueError, match="x_min .* must be below x_max"):
        Zones.from_list([vals[1], vals[0]] + vals[2:])
    with pytest.raises(ValueError, match="x_obs_start .* must be below x_obs_end"):
        Zones.from_list(vals[:4] + [2.0, 1.0] + vals[6:])
    with pytest.raises(ValueError, match="y_half .* must be positive"):
        Zones.from_list(vals[:6] + [0.0] + vals[7:])
