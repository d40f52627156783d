"""QoS profiles of the /lhd topics, in one place for every node and tool.

MEASUREMENT_QOS  reliable, keep-last 5: a reliable publisher matches reliable and
                 best-effort (sensor-data) subscribers alike; a short queue never delays fresh
                 data behind stale data; lockstep simulation must not lose a state.
COMMAND_QOS      reliable, keep-last 1: only the newest command matters, and receivers time
                 out on arrival (0.3 s), so a silent link stops the machine.
STATUS_QOS       reliable + transient local, keep-last 10: a late subscriber (a launcher,
                 lhd echo) still gets the current state of the episode.
WATCH_QOS        STATUS_QOS with a history of 5,000 on the reading side, for a reader that must
                 hear every episode's end (lhd up sim): the status comes every control step, and a
                 launcher busy for ten of them (a slow callback, a loaded machine) lost an end from
                 a history of 10. Only for readers that take every message in order and drain fast:
                 one that acts on the latest status would act on a backlog (lhd up twin, up real
                 keep STATUS_QOS). Matches STATUS_QOS publishers.
LATCHED_QOS      reliable + transient local, keep-last 1: values that change once per attempt
                 (pile slope, toe, end zone); a subscriber that starts later gets the latest,
                 with its original stamp, and no older value.
"""
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

MEASUREMENT_QOS = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
COMMAND_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
STATUS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
WATCH_QOS = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
LATCHED_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
