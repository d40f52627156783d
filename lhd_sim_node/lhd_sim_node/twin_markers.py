"""visualization_msgs/MarkerArray of the digital twin (RViz, Foxglove): the pile's surface, the
zones, the bucket tip's trajectory and the FEE force, from the plain arrays of sim_sensors
(pile_surfaces, zone_boxes, TipTrail.array, fee_arrow).

The builder lives in lhd_loading_ros.ros.markers, shared with the supervisor's markers (the same
namespaces, ids and colours on /lhd/twin/markers and /lhd/supervisor/markers); this module keeps
the twin's import path.
"""
from lhd_loading_ros.ros.markers import (MAX_SLICES, NS_FEE, NS_PILE, NS_TIP, NS_ZONES, ZONE_COLORS,  # noqa: F401
                                         ZONE_IDS, marker_array)
