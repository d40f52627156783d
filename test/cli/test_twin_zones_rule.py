"""`lhd up twin` arms only on zones of the current pile (cli/up_twin.Watch.zones_caught_up): within
8 cm of the twin's truth, or, on a rough face whose scanned slice is 2-3 deg off the pile's plane,
of the end-zone rule at the slope node's own fit of a scan taken 2 s after the pile was made."""
import math

from lhd_loading_ros.cli.up_twin import SLOPE_SETTLE_S, Watch
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.end_zone import nominal_density
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.zones import Zones


def _watch(published, truth, fit, scan_t, pile_t=100.0):
    w = Watch.__new__(Watch)            # the rule alone: no node, no subscriptions
    w.zones, w.truth_zones = published.as_list(), truth.as_list()
    w.slope_fit, w.slope_scan_t, w.pile_t = fit, scan_t, pile_t
    return w


def test_zones_of_this_pile_by_truth_or_by_the_stacks_own_settled_fit():
    cfg = load_config()
    tp, rho = TaskParams.from_config(cfg), nominal_density(cfg)

    def own(a, t):
        return Zones.for_measured_pile(a, t, rho, tp)

    truth = own(math.radians(25.0), 0.0)
    slice_fit = (math.radians(22.3), 0.02)              # a rough face's slice: 2.7 deg under the plane
    estimate = own(*slice_fit)
    assert abs(estimate.x_cutoff - truth.x_cutoff) > 0.08   # the truth rule alone never lets it arm
    previous = own(math.radians(20.0), 0.0)                 # the last pile's zones, still latched
    settled = 100.0 + SLOPE_SETTLE_S + 0.2
    # the stack's zones are those of its own settled fit: this pile's
    assert _watch(estimate, truth, slice_fit, settled).zones_caught_up(own)
    assert not _watch(estimate, truth, slice_fit, settled).zones_caught_up()          # without the rule: truth only
    # a fit of a scan too soon after the pile was made may still be the last pile's median
    assert not _watch(estimate, truth, slice_fit, 100.5).zones_caught_up(own)
    # the end-zone node has not republished yet: the latched zones are the last pile's
    assert not _watch(previous, truth, slice_fit, settled).zones_caught_up(own)
    # a plane pile: within 8 cm of the truth as before, whatever the fit
    assert _watch(own(math.radians(25.3), 0.01), truth, None, 100.1).zones_caught_up(own)
