"""zones_for_slope_estimate: the zones the machine works with when the LiDAR's slope is wrong (the
end-zone node builds them from the estimate). Checked against numbers worked by hand from the
wedge, against the end-zone node's own computation (Zones.for_measured_pile at the estimate), and
for its properties."""
import math

import pytest

from lhd_loading_ros.task.zones import ESTIMATE_SLOPE_RANGE_DEG, Zones, zones_for_slope_estimate

r = math.radians
RHO = 1880.0      # kg/m^3, the config's nominal gravel


def test_a_15_deg_pile_told_30_deg_by_hand(params):
    """A 15 deg pile (h 0.68 m, w 0.4 m, 1,880 kg/m^3) told 30 deg. By hand:
    x_max = sqrt(2 x 170 / (1880 x 0.4 x tan a)): 1.2990 m at 15 deg, 0.8849 m at 30 deg;
    x_min (65 kg): 0.8032 / 0.5472 m; the restricted zone at 0.68 / tan 30 - 0.1 = 1.0778 m."""
    assert (params.m_min, params.m_max, params.h_pile, params.w_pile, params.d_cutoff) == (65.0, 170.0, 0.68, 0.4, 0.1)
    true = Zones.for_measured_pile(r(15), 0.0, RHO, params)
    assert true.x_max == pytest.approx(1.2990, abs=5e-4) and true.x_min == pytest.approx(0.8032, abs=5e-4)
    est = zones_for_slope_estimate(true, r(15), r(30), params)
    assert est.x_max == pytest.approx(0.8849, abs=5e-4)
    assert est.x_min == pytest.approx(0.5472, abs=5e-4)
    assert est.x_cutoff == pytest.approx(0.68 / math.tan(r(30)) - 0.1, abs=1e-9)
    assert est.x_cutoff == pytest.approx(1.0778, abs=5e-4)
    # what does not depend on the slope stays
    assert (est.z_min, est.x_obs_start, est.x_obs_end, est.y_half, est.z_top) == (
        true.z_min, true.x_obs_start, true.x_obs_end, true.y_half, true.z_top)


@pytest.mark.parametrize("true_deg, est_deg", [(30, 15), (15, 30), (20, 25), (25, 10), (15, 45), (35, 20)])
def test_the_end_zone_nodes_zones_at_the_estimate(params, true_deg, est_deg):
    """From the wedge's zones at the true slope, the estimate's are the end-zone node's at the
    estimated slope (same density), wherever the wedge is deep enough to hold m_max."""
    true = Zones.for_measured_pile(r(true_deg), 0.0, RHO, params)
    est = zones_for_slope_estimate(true, r(true_deg), r(est_deg), params)
    node = Zones.for_measured_pile(r(est_deg), 0.0, RHO, params)
    for f in ("x_min", "x_max", "x_cutoff"):
        assert getattr(est, f) == pytest.approx(getattr(node, f), abs=1e-9), f


def test_no_error_no_change_and_the_pile_keeps_its_own_zones(params):
    """The pile's zones (voxels, rocks, its own density) pass through unchanged at zero error, and
    an error scales them by sqrt(tan a_true / tan a_est): an underestimate puts the end zone deeper."""
    z = Zones(x_min=0.61, x_max=0.97, z_min=0.35, x_cutoff=1.25, x_obs_start=-0.1, x_obs_end=1.37, y_half=0.2,
              z_top=1.0)
    assert zones_for_slope_estimate(z, r(25), r(25), params) is z
    deeper = zones_for_slope_estimate(z, r(25), r(20), params)
    k = math.sqrt(math.tan(r(25)) / math.tan(r(20)))
    assert deeper.x_max == pytest.approx(0.97 * k) and deeper.x_min == pytest.approx(0.61 * k)
    assert deeper.x_max > z.x_max and deeper.x_cutoff > z.x_cutoff


def test_capped_at_the_estimated_wedges_depth(params):
    """A 10 deg pile told 50 deg: the scaled end zone would lie beyond the told wedge's back end
    (0.68 / tan 50 = 0.571 m); it stops there, as for_measured_pile's wedge does."""
    true = Zones.for_measured_pile(r(10), 0.0, RHO, params)
    est = zones_for_slope_estimate(true, r(10), r(50), params)
    L = 0.68 / math.tan(r(50))
    assert est.x_max <= L + 1e-12 and est.x_min <= est.x_max


@pytest.mark.parametrize("est_deg", [0.0, 4.9, 50.1, -5.0, float("nan")])
def test_an_estimate_the_end_zone_node_refuses_is_refused(params, est_deg):
    true = Zones.for_measured_pile(r(15), 0.0, RHO, params)
    with pytest.raises(ValueError, match="outside the LiDAR's physical range"):
        zones_for_slope_estimate(true, r(15), r(est_deg), params)
    assert ESTIMATE_SLOPE_RANGE_DEG == (5.0, 50.0)


def test_the_end_zone_nodes_zones_at_the_nominal_density_by_hand(params):
    """zones_at_nominal_density: what the end-zone node publishes for an estimate, whatever the pile.
    By hand at 20 deg and 1,880 kg/m^3 (tan 20 deg = 0.363970): x_max = sqrt(2 x 170 / (1880 x 0.4 x
    0.363970)) = sqrt(340 / 273.7056) = 1.114545 m, x_min = sqrt(130 / 273.7056) = 0.689175 m, the cut at
    0.68 / 0.363970 - 0.1 = 1.768285 m; at 1,550 kg/m^3 (a light pile's density, which the node does not know) x_max would be 1.114545 x sqrt(1880 / 1550) = 1.227469 m.
    The node's own function (end_zone.zones_of_pile, toe 0) gives the same zones."""
    from lhd_loading_ros.task.end_zone import zones_at_nominal_density, zones_of_pile

    z = zones_at_nominal_density(r(20), RHO, params)
    assert z.x_max == pytest.approx(1.114545, abs=2e-6) and z.x_min == pytest.approx(0.689175, abs=2e-6)
    assert z.x_cutoff == pytest.approx(1.768285, abs=2e-6)
    assert z == zones_of_pile(r(20), 0.0, RHO, params)
    light = zones_at_nominal_density(r(20), 1550.0, params)
    assert light.x_max == pytest.approx(1.227469, abs=2e-6)


@pytest.mark.parametrize("est_deg, needle", [(4.9, "outside the LiDAR's physical range"),
                                             (50.1, "outside the LiDAR's physical range"),
                                             (float("nan"), "outside the LiDAR's physical range"),
                                             (46.0, "less than m_max")])
def test_the_nominal_density_zones_refuse_what_the_end_zone_node_refuses(params, est_deg, needle):
    """Where the node publishes nothing, neither does its counterpart: an estimate outside the LiDAR's
    5-50 deg, and a wedge too steep to hold m_max at the nominal density: 1880 x 0.4 x 0.68^2 / (2 tan a)
    >= 170 kg holds up to tan a = 1.02322, a = 45.64 deg by hand (the old capped zones put x_max behind the
    cut there)."""
    from lhd_loading_ros.task.end_zone import zones_at_nominal_density

    with pytest.raises(ValueError, match=needle):
        zones_at_nominal_density(r(est_deg), RHO, params)
    if est_deg == 46.0:
        zones_at_nominal_density(r(45.6), RHO, params)      # just below the limit: published
