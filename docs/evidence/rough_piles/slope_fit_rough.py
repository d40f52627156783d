"""The LiDAR slope fit (perception/slope.fit_slope, the slope node's parameters) on plane and rough
piles (2026-11-28): for each slope, 12 piles x 8 scans of the twin's LiDAR model (range noise 1 cm,
2 % outliers, the draw point's clutter), the error of each scan's alpha against the pile's plane,
and the spread of alpha over the 8 scans of one pile (the pile does not move between them). Next to
it, what one scan line can know at best: the least-squares slope of the scanned slice's own profile.
slope_fit_rough.txt is of the fit with its whole-face stage (perception/slope.refine_face, added the
same day); the figures of the RANSAC stage alone are kept in docs/perception.md "Rough faces".

    .venv/bin/python docs/evidence/rough_piles/slope_fit_rough.py > docs/evidence/rough_piles/slope_fit_rough.txt
"""
import math

import numpy as np

from lhd_loading_ros.perception.geometry import apply, transform
from lhd_loading_ros.perception.slope import NoSlope, fit_slope, scan_to_points
from lhd_loading_ros.perception.synthetic import DrawPoint
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.pile import SoilRanges, VoxelPile
from lhd_sim_node import sim_sensors as ss

SLOPES = (10, 15, 20, 25, 30, 35)
RELIEFS = (0.0, 0.03)          # m, sd of the surface relief (correlation length 0.15 m)
PILES, SCANS = 12, 8


def main() -> None:
    cfg = load_config()
    soil = SoilRanges.from_config(cfg)
    lidar = ss.LidarModel.from_params(None)                  # the slope node's default pose
    T = transform([0.6, 0.0, 1.6], [math.pi / 2, 0.0, 0.0])
    kw = dict(floor_z=0.03, max_z=1.5, max_abs_y=0.3, min_points=30, iterations=200, threshold=0.02,
              slope_min=math.radians(5), slope_max=math.radians(50))
    clutter = DrawPoint(machine=False)
    print("relief sd [m] | slope [deg] | |alpha error| mean / max [deg] | alpha spread over 8 scans of a pile, "
          "mean / max [deg] | no slope [scans] | the scanned slice's own LS slope, |error| mean / max [deg]")
    for sd in RELIEFS:
        for a in SLOPES:
            err, spread, slice_err, none = [], [], [], 0
            for seed in range(PILES):
                p = VoxelPile.generate(np.random.default_rng(seed), math.radians(a), 0.68, 0.4, 60, 7, 10, soil)
                if sd:
                    p.roughen(np.random.default_rng(seed + 100), sd, 0.15)
                j = ss._slice_index(p, float(lidar.T_pile_sensor[1, 3]))
                face = (p.top[j] > 0.03) & (p.top[j] < p.h - 0.03)
                slice_err.append(math.degrees(math.atan(np.polyfit(p.x_centers[face], p.top[j][face], 1)[0])) - a)
                scan_rng, fit_rng = np.random.default_rng(seed), np.random.default_rng(0)
                al = []
                for _ in range(SCANS):
                    r, amin, ainc = ss.lidar_scan(lidar, p, scan_rng, clutter)
                    try:
                        f = fit_slope(apply(T, scan_to_points(amin, ainc, r, lidar.range_min, lidar.range_max)),
                                      fit_rng, **kw)
                    except NoSlope:
                        none += 1
                        continue
                    al.append(math.degrees(f.alpha))
                err += [v - a for v in al]
                if al:
                    spread.append(max(al) - min(al))
            e, s, se = np.abs(err), np.array(spread), np.abs(slice_err)
            print(f"{sd:.2f} | {a} | {e.mean():.2f} / {e.max():.2f} | {s.mean():.2f} / {s.max():.2f} | {none} | "
                  f"{se.mean():.2f} / {se.max():.2f}")


if __name__ == "__main__":
    main()
