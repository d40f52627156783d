"""`lhd bag recover BAG [--out DIR]`: the readable part of an attempt's bag that was never closed
(the recorder killed, the computer lost power) as a complete rosbag2 folder (cli/bag_recover.py),
which `lhd replay` and `ros2 bag play` then read. Exit 0, 1 when nothing could be recovered, 2
for bad arguments, 3 when the bag was written but topics were left out (each named with the reason)."""
from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd bag", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    rec = sub.add_parser("recover", help="rewrite a never-closed bag (MCAP or sqlite3) as a complete one beside it")
    rec.add_argument("bag", help="the attempt's bag folder (runs/.../bags/attempt_NNNN)")
    rec.add_argument("--out", default=None, help="folder to write (default: BAG_recovered; never overwritten)")
    args = ap.parse_args(argv)
    from lhd_loading_ros.cli.bag_recover import RecoverError, recover

    try:
        out, scan = recover(args.bag, args.out)
    except (RecoverError, OSError) as exc:
        print(f"lhd bag recover: {exc}", file=sys.stderr)
        return 1
    written = sum(scan.written.values())
    if scan.storage == "sqlite3":
        where = "the rows committed before the recorder stopped (sqlite3)"
    else:
        where = (f"{scan.chunks} chunks, " + ("the whole file" if scan.truncated_at is None else
                                              f"up to byte {scan.truncated_at} (the rest was cut off)"))
    # the messages written, not those scanned (a review, 2026-11-30: dropped topics were counted)
    print(f"lhd bag recover: {written} messages on {len(scan.written)} topics from {where}, written to {out} "
          f"(`lhd replay {out}`)")
    for topic, why in sorted(scan.dropped.items()):
        print(f"lhd bag recover: WARNING: {topic} left out: {why}", file=sys.stderr)
    return 3 if scan.dropped else 0


if __name__ == "__main__":
    sys.exit(main())
