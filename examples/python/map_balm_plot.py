#!/usr/bin/env python3
"""Map balm_os0 by SLAM from its scans alone and plot the 2D occupancy grid, in metres, with the
trajectory over it (matplotlib).

    PYTHONPATH=build/python python3 examples/python/map_balm_plot.py --out balm_os0_grid.png
"""

import argparse
import os
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")  # no display needed: the figure goes to a file
import matplotlib.pyplot as plt
from matplotlib.patches import Patch

import hmap


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=pathlib.Path, default=pathlib.Path(os.environ.get("HMAP_DATA_DIR", "../shared/data")),
                    help="the folder holding balm_os0 (default: $HMAP_DATA_DIR, else ../shared/data)")
    ap.add_argument("--scans", type=int, default=None, help="map the first N scans only (default: all 80)")
    ap.add_argument("--size", default="1000x800", help="the figure's size in pixels, WxH (default 1000x800)")
    ap.add_argument("--out", type=pathlib.Path, required=True, help="the PNG to write")
    a = ap.parse_args()
    folder = a.data / "balm_os0"
    if not (folder / "velodyne").is_dir():
        print(f"{ap.prog}: error: {folder} holds no velodyne/ scans (give --data DIR or set HMAP_DATA_DIR)",
              file=sys.stderr)
        return 2
    width, height = (int(v) for v in a.size.split("x"))

    # SLAM from the scans alone, with the parameters `hmap slam` chooses from the first scan.
    scans = hmap.io.kitti_sequence(folder, max_scans=a.scans)
    first, _, _ = next(scans)
    slam = hmap.slam.Slam(hmap.params_for_scan(first)["params"])
    slam.process(first)
    for points, _, stamp in scans:
        slam.process(points, stamp)

    image, vp = hmap.render.grid(slam.map)  # the 2D grid as map_server draws it, derived from the HVoxels
    fig, ax = plt.subplots(figsize=(width / 100, height / 100), dpi=100)
    ax.imshow(image, extent=vp.extent, interpolation="nearest")  # extent: the axes in metres
    ax.plot(slam.poses[:, 0, 3], slam.poses[:, 1, 3], "-", color="tab:red", lw=2)
    ax.plot(slam.poses[0, 0, 3], slam.poses[0, 1, 3], "o", color="tab:red")
    ax.legend(handles=[Patch(color="white", ec="black", label="free"), Patch(color="black", label="occupied"),
                       Patch(color=(205 / 255,) * 3, label="unknown"),
                       plt.Line2D([], [], color="tab:red", marker="o", label=f"SLAM trajectory ({slam.scans} scans)")],
              loc="upper right")
    ax.set(xlabel="x [m]", ylabel="y [m]", title=f"balm_os0: 2D occupancy grid from SLAM ({vp.m_per_px:g} m per pixel)")
    fig.savefig(a.out, dpi=100)
    print(f"wrote {a.out}: {width}x{height} pixels, {slam.scans} scans, the grid {vp.width}x{vp.height} px "
          f"over x {vp.extent[0]:.1f}..{vp.extent[1]:.1f} m, y {vp.extent[2]:.1f}..{vp.extent[3]:.1f} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
