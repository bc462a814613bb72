#!/usr/bin/env python3
"""Simulate a VLP-16 driving out of the parking garage, map it with the hybrid mapper, and save
the map, its 2D grid for ROS (PGM + YAML) and a picture of that grid (PNG).

    PYTHONPATH=build/python python3 examples/python/simulate_and_map.py --out out/py_parking
"""

import argparse
import json
import pathlib

import numpy as np

import hmap


def grid_picture(grid):
    """The 2D grid as an RGB image, north up: occupied black, free white, unknown grey."""
    p = grid.probability[::-1]                       # row 0 of the grid is the southernmost
    shade = np.where(np.isnan(p), 0.5, 1.0 - p)      # p = 1 black, p = 0 white
    return np.repeat((shade * 255).round().astype(np.uint8)[:, :, None], 3, axis=2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument("--frames", type=int, default=40, help="frames of the 10 Hz route (every 5th is mapped)")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)

    scene = hmap.sim.Scene("parking")
    path = hmap.sim.car_path(hmap.sim.route("parking"))   # the route `hmap simulate --scene parking` drives
    lidar = hmap.sim.Sensor("vlp16", seed=a.seed)
    params = hmap.Params("outdoor")
    params.map.cell_size = 0.2
    mapper = hmap.HybridMapper(params)
    for k in range(0, min(a.frames, len(path)), 5):
        scan = lidar.scan(scene, path.poses[k], path.times[k])
        mapper.integrate(scan["points"], path.poses[k])   # points in the sensor frame, T_map_sensor

    m = mapper.map
    m.save(a.out / "map.hmap")
    hmap.io.write_pgm(m, a.out / "grid")                  # grid.pgm + grid.yaml, as `hmap export --pgm`
    grid = m.grid()
    hmap.io.write_png(a.out / "grid.png", grid_picture(grid))
    stats = m.stats()
    summary = {"cells": stats["cells"], "hvoxels": stats["hvoxels"], "grid_shape": list(grid.probability.shape),
               "grid_origin": list(grid.origin), "resolution": grid.resolution}
    (a.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"{stats['cells']} cells, {stats['hvoxels']} HVoxels; wrote {a.out}/map.hmap, grid.pgm + .yaml, grid.png")


if __name__ == "__main__":
    main()
