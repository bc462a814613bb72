#!/usr/bin/env python3
"""Simulate a drive through the parking scene, write it as a KITTI folder, run SLAM on it scan by
scan with the noisy wheel odometry as the guess, and measure the trajectory against the truth.

    PYTHONPATH=build/python python3 examples/python/slam_and_evaluate.py --out out/py_slam
"""

import argparse
import json
import pathlib

import numpy as np

import hmap


def simulate(out, frames, stride, seed):
    """A recording in the KITTI layout, as `hmap simulate --frames F --stride S` writes one."""
    scene = hmap.sim.Scene("parking")
    path = hmap.sim.car_path(hmap.sim.route("parking"))
    lidar = hmap.sim.Sensor("vlp16", seed=seed)
    ks = list(range(0, len(path), stride))[:frames]
    scans = [lidar.scan(scene, path.poses[k], path.times[k])["points"] for k in ks]
    truth = path.poses[ks]
    odometry = hmap.sim.noisy_odometry(truth, seed=seed)
    hmap.sim.write_sequence(out, scans, truth, path.times[ks], odometry=odometry)
    return truth, odometry


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--stride", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()

    truth, odometry = simulate(a.out / "seq", a.frames, a.stride, a.seed)
    scans = hmap.io.kitti_sequence(a.out / "seq")
    first, _, _ = next(scans)
    slam = hmap.slam.Slam(hmap.params_for_scan(first)["params"])   # the parameters `hmap slam` chooses
    slam.process(first)
    # Odometry in SLAM's frame (the first scan's): the guess for x, y and yaw of each scan.
    T_first_world = np.linalg.inv(odometry[0])
    for k, (points, _, stamp) in enumerate(scans, start=1):
        slam.process(points, stamp, guess=T_first_world @ odometry[k])
    estimate = odometry[0] @ slam.poses    # back in the world frame, from the first (true) pose
    metrics = hmap.eval.trajectory(truth, estimate)
    odometry_metrics = hmap.eval.trajectory(truth, odometry)
    result = {"scans": slam.scans, "ate_rmse_m": metrics["ate_rmse_m"], "odometry_ate_rmse_m": odometry_metrics["ate_rmse_m"],
              "map_cells": slam.map.stats()["cells"]}
    np.savetxt(a.out / "poses.txt", estimate[:, :3, :].reshape(len(estimate), 12), fmt="%.9g")
    (a.out / "result.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"SLAM on {slam.scans} scans: ATE {result['ate_rmse_m']:.3f} m (odometry alone "
          f"{result['odometry_ate_rmse_m']:.3f} m); wrote {a.out}/poses.txt, result.json")


if __name__ == "__main__":
    main()
