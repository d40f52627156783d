"""Independent hand-calculation references of the pile physics, for the tests of issue 13
(test_physics_reference.py checks them against literal hand numbers; test_fee_face.py and
test_bucket_body.py compare the simulator with them).

One source of truth: the math lives in the package (lhd_sim_node/reference_mechanics.py) so that
`lhd validate physics` prints the same references; this module re-exports it for the tests
(`from reference_mechanics import passive_wedge, Soil, ...` from test/sim/). It never imports the
simulator's fee.py, fee_kernel.py or bucket_body.py, and neither does the package module.
"""
from lhd_sim_node.reference_mechanics import (GRAVEL_DENSITY, G, Breakout, BucketGeometry, Soil,  # noqa: F401
                                              WedgeForce, rating_density,
                                              breakout, bucket_capacity_at_pitch, bucket_capacity_iso7546,
                                              contents_centroid,
                                              face_frame, passive_wedge, pile_surface, wedge_at)
