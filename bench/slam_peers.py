#!/usr/bin/python3
"""hmap slam beside the LiDAR-only peers on the same KITTI-layout sequences, in one script.

Runs, per sequence: `hmap slam --kitti DIR --out ...` (defaults, no reference attitude),
Debian's Open3D point-to-plane ICP (scan to scan, every point, constant-velocity guess), and KISS-ICP built
from ../shared/peers (drivers/build_kiss_icp.sh; skipped with a message when the folder is absent).
Scores every trajectory with `hmap eval traj --json` against the sequence's poses.txt when it has
one, else against the Open3D trajectory (then: mean per-frame motion difference and end-point
difference, the issue's figures for kitti_hdl64_seq16).

usage: bench/slam_peers.py [--hmap build/bin/hmap] [--data ../shared/data] [--work out/slam_peers]
                           [SEQ ...]   (default: balm_os0 kitti_hdl64_seq16)
Needs python3-open3d and python3-numpy (make bench-slam installs them).
"""
import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time

try:
    import numpy as np
    import open3d as o3d
except ImportError as e:  # pragma: no cover
    sys.exit(f"slam_peers.py: {e.name} is missing (apt-get install python3-open3d python3-numpy, or make bench-slam)")


def read_kitti_poses(path):
    out = []
    with open(path) as f:
        for line in f:
            v = [float(x) for x in line.split()]
            if len(v) != 12:
                continue
            T = np.eye(4)
            T[:3, :] = np.array(v).reshape(3, 4)
            out.append(T)
    return out


def write_kitti_poses(path, poses):
    with open(path, "w") as f:
        for T in poses:
            f.write(" ".join(f"{x:.9g}" for x in T[:3, :].reshape(-1)) + "\n")


def scans_of(seq):
    d = os.path.join(seq, "velodyne")
    return [os.path.join(d, n) for n in sorted(os.listdir(d)) if n.endswith(".bin")]


def cpu_seconds():
    r = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime + c.ru_utime + c.ru_stime


# Open3D's settings, the same for every sequence: every point (no voxel grid: at 0.2 m its
# quantisation moved KITTI's end point 3-6 cm from every finer run, docs/SLAM.md "Session 35"),
# normals from the neighbours within 0.5 m, correspondences within 0.6 m.
O3D_NORMAL_RADIUS = 0.5  # [m]
O3D_MAX_DISTANCE = 0.6  # [m]


def run_open3d(seq, max_range, constant_velocity):
    """Point-to-plane ICP scan to scan, KITTI scans as float32 x y z i; the initial guess is the
    last motion (constant_velocity) or none (a hand-held sensor's turn rate changes sign between
    scans: constant velocity throws ICP out of its basin on balm_os0)."""
    poses = [np.eye(4)]
    prev = None
    delta = np.eye(4)
    for path in scans_of(seq):
        xyz = np.fromfile(path, dtype=np.float32).reshape(-1, 4)[:, :3].astype(np.float64)
        r = np.linalg.norm(xyz, axis=1)
        xyz = xyz[(r > 1.0) & (r < max_range)]
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
        pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=O3D_NORMAL_RADIUS, max_nn=30))
        if prev is not None:
            reg = o3d.pipelines.registration.registration_icp(
                pc, prev, O3D_MAX_DISTANCE, delta, o3d.pipelines.registration.TransformationEstimationPointToPlane(),
                o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=50))
            poses.append(poses[-1] @ reg.transformation)
            delta = reg.transformation if constant_velocity else np.eye(4)
        prev = pc
    return poses


def anchored(path, work):
    """The trajectory re-expressed from its first pose (T0⁻¹·Tk): every system and the reference
    start at the identity, so a map frame levelled on the first scan's floor (hmap) is compared
    in the same frame as one that is the first sensor frame (the peers, the references)."""
    poses = read_kitti_poses(path)
    inv0 = np.linalg.inv(poses[0])
    out = os.path.join(work, "anchored_" + os.path.basename(os.path.dirname(path)) + "_" + os.path.basename(path))
    write_kitti_poses(out, [inv0 @ T for T in poses])
    return out


def evaluate(hmap, gt_path, est_path):
    out = subprocess.run([hmap, "eval", "traj", "--gt", gt_path, "--est", est_path, "--json"],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def motion_difference(ref, est):
    """Mean per-frame motion difference [m] and end-point difference [m] against a reference."""
    diffs = []
    for k in range(1, min(len(ref), len(est))):
        dr = np.linalg.inv(ref[k - 1]) @ ref[k]
        de = np.linalg.inv(est[k - 1]) @ est[k]
        diffs.append(np.linalg.norm(dr[:3, 3] - de[:3, 3]))
    end = np.linalg.norm(ref[-1][:3, 3] - est[-1][:3, 3])
    return float(np.mean(diffs)), float(end)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("seqs", nargs="*", default=["balm_os0", "kitti_hdl64_seq16"])
    ap.add_argument("--hmap", default="build/bin/hmap")
    ap.add_argument("--data", default=os.environ.get("HMAP_DATA_DIR", "../shared/data"))
    ap.add_argument("--peers", default="../shared/peers")
    ap.add_argument("--work", default="out/slam_peers")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    kiss = None
    build = os.path.join(args.peers, "drivers", "build_kiss_icp.sh")
    if os.path.exists(build):
        kiss = subprocess.run(["bash", build, os.path.abspath(os.path.join(args.work, "build-peers"))],
                              check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1]
    else:
        print(f"KISS-ICP skipped: {build} is absent")
    print("| sequence | system | ATE RMSE [m] | ATE after SE(3) alignment [m] | RPE per frame [m] | "
          "mean frame motion vs ref [m] | end point vs ref [m] | wall s | CPU s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in args.seqs:
        seq = os.path.join(args.data, name)
        if not os.path.isdir(seq):
            print(f"{name}: skipped ({seq} is absent)")
            continue
        max_range = 25.0 if "os0" in name else 50.0
        gt = os.path.join(seq, "poses.txt")
        work = os.path.join(args.work, name)
        os.makedirs(work, exist_ok=True)
        runs = {}
        t0, c0 = time.time(), cpu_seconds()
        subprocess.run([args.hmap, "slam", "--kitti", seq, "--out", os.path.join(work, "hmap")], check=True,
                       capture_output=True)
        runs["hmap slam (defaults)"] = (os.path.join(work, "hmap", "poses.txt"), time.time() - t0, cpu_seconds() - c0)
        t0, c0 = time.time(), cpu_seconds()
        o3d_poses = run_open3d(seq, max_range, constant_velocity="os0" not in name)
        path = os.path.join(work, "open3d.txt")
        write_kitti_poses(path, o3d_poses)
        runs["Open3D point-to-plane ICP"] = (path, time.time() - t0, cpu_seconds() - c0)
        if kiss:
            path = os.path.join(work, "kiss.txt")
            t0, c0 = time.time(), cpu_seconds()
            subprocess.run([kiss, seq, path, str(max_range)], check=True, capture_output=True)
            runs["KISS-ICP (defaults)"] = (path, time.time() - t0, cpu_seconds() - c0)
        ref = anchored(gt if os.path.exists(gt) else runs["Open3D point-to-plane ICP"][0], work)
        ref_poses = read_kitti_poses(ref)
        for system, (path, wall, cpu) in runs.items():
            path = anchored(path, work)
            e = evaluate(args.hmap, ref, path)
            md, end = motion_difference(ref_poses, read_kitti_poses(path))
            print(f"| {name} | {system} | {e['ate_rmse_m']:.3f} | {e['ate_rmse_aligned_m']:.3f} | "
                  f"{e['rpe_frame_trans_rmse_m']:.4f} | {md:.4f} | {end:.3f} | {wall:.1f} | {cpu:.1f} |")
        # The same trajectories as a picture: hmap's and each peer's over the reference, seen from above.
        picture = os.path.join(work, "trajectories.png")
        command = [args.hmap, "eval", "traj", "--gt", ref, "--est", runs["hmap slam (defaults)"][0], "--plot", picture]
        for system, (path, _, _) in runs.items():
            is_reference = not os.path.exists(gt) and system == "Open3D point-to-plane ICP"  # drawn as the truth
            if system != "hmap slam (defaults)" and not is_reference:
                command += ["--plot-path", f"{path}={system}"]
        subprocess.run(command, check=True, capture_output=True)
        print(f"(reference for {name}: {'poses.txt' if os.path.exists(gt) else 'Open3D ICP'}; every trajectory from its first pose; "
              f"drawn in {picture})")


if __name__ == "__main__":
    main()
