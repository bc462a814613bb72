#!/usr/bin/python3
"""hmap slam at its defaults on every route with an honest truth, over sensors and noise seeds.

One whole-route figure decides nothing on the simulated parking route: without odometry its RPE
moves between 1.1 and 2.6 % from one noise seed to the next with the same code (docs/SLAM.md).
This runs the commands a user types (`hmap simulate`, `hmap slam --kitti DIR --out O`, `hmap eval
traj --json`) on:

- the parking long route (garage, ramp, street, side road, 310 m) with a VLP-16 on --seeds noise
  seeds, and with an HDL-64 and an OS0-64 on seed 1; each with and without --odometry;
- a 0.3 km drive through the town with the three LiDARs (no odometry);
- 60 frames (3 m) through the office with the three LiDARs, and the office with a Kinect
  (166 frames, 27.8 m) with and without odometry;
- the three LiDARs from a small room into a hall (bench/scenes/room_to_hall.json, 166 frames), and
  from the same room with its door shut for the first scans (bench/scenes/closed_room_to_hall.json);
- the real balm_os0 (reference poses) when the data folder has it, and kitti_hdl64_seq16 against
  the Open3D ICP trajectory bench/slam_peers.py writes.

The built-in scenes' walls are parallel to the first scan's axes, and so to the map's grid: a
lidar mounted straight along a street. `--mount-yaw DEG` turns the simulated lidars (not the
Kinect) so that they are not; the parking route's figures move with it (docs/SLAM.md).

Simulated routes are made once into --work and reused. Figures per run: RPE per distance [%]
(KITTI's 100-800 m segments where the route is long enough, else 10-80 % of the path), ATE from
the first pose [m], end point from the first pose [m]. Then per group (a sensor on a route, over
seeds) the mean and the worst. `--json F` writes them; `--baseline F` prints each figure beside
a saved run's and counts better and worse. Arguments after `--` go to every `hmap slam`, e.g.
`-- --set slam.wall_refine=1`.

usage: bench/slam_suite.py [--hmap build/bin/hmap] [--data ../shared/data] [--work out/slam_suite]
                           [--seeds 4] [--jobs 2] [--only REGEX] [--mount-yaw DEG] [--json F]
                           [--baseline F] [-- hmap slam arguments]
"""
import argparse
import concurrent.futures
import json
import os
import re
import subprocess
import sys
import time


def cases(seeds, data, kitti_reference, mount_yaw):
    """(name, group, simulate arguments or None, data folder or None, slam arguments, reference
    poses or None for the folder's poses.txt). With a mount yaw the lidars are turned by it (the
    Kinect cannot be: it would look elsewhere)."""
    out = []
    turn = ["--mount-yaw", f"{mount_yaw:g}"] if mount_yaw else []
    tag = f"-turned{mount_yaw:g}" if mount_yaw else ""
    label = f" turned {mount_yaw:g} deg" if mount_yaw else ""
    for sensor, seed_list in (("vlp16", range(1, seeds + 1)), ("hdl64", [1]), ("os0-64", [1])):
        for seed in seed_list:
            sim = ["--scene", "parking", "--sensor", sensor, "--long-route", "--seed", str(seed), *turn]
            route = f"parking-{sensor}-s{seed}{tag}"
            out.append((f"{route}-odometry", f"parking {sensor}{label}, odometry", sim, None,
                        ["--odometry", "@/odometry.txt"], None))
            out.append((f"{route}", f"parking {sensor}{label}", sim, None, [], None))
    for sensor in ("vlp16", "hdl64", "os0-64"):
        out.append((f"town-{sensor}{tag}", f"town {sensor}{label}",
                    ["--scene", "city", "--sensor", sensor, "--route-km", "0.3", *turn], None, [], None))
    for sensor in ("vlp16", "hdl64", "os0-64"):
        out.append((f"office-{sensor}{tag}", f"office {sensor}{label}",
                    ["--scene", "office", "--sensor", sensor, "--frames", "60", *turn], None, [], None))
    # A LiDAR whose first scan sees a 3.6 x 2.3 m room alone, then the 40 x 35 m hall its door opens
    # into (the office robot's route; docs/SLAM.md, "Session 33").
    hall = os.path.join(os.path.dirname(os.path.abspath(__file__)), "scenes", "room_to_hall.json")
    for sensor in ("vlp16", "hdl64", "os0-64"):
        out.append((f"hall-{sensor}{tag}", f"room to hall {sensor}{label}",
                    ["--scene-file", hall, "--sensor", sensor, "--stride", "4", *turn], None, [], None))
    # The same with the door shut until 1 s (it slides open by 2.5 s): the first scan sees nothing
    # beyond 5 m, where a LiDAR's rings are read from (docs/SLAM.md, "Session 34").
    closed = os.path.join(os.path.dirname(os.path.abspath(__file__)), "scenes", "closed_room_to_hall.json")
    for sensor in ("vlp16", "hdl64", "os0-64"):
        out.append((f"closed-{sensor}{tag}", f"closed room to hall {sensor}{label}",
                    ["--scene-file", closed, "--sensor", sensor, "--stride", "4", *turn], None, [], None))
    kinect = ["--scene", "office", "--sensor", "kinect", "--stride", "4"]
    out.append(("office-kinect-odometry", "office kinect, odometry", kinect, None, ["--odometry", "@/odometry.txt"], None))
    out.append(("office-kinect", "office kinect", kinect, None, [], None))
    balm = os.path.join(data, "balm_os0")
    if os.path.isfile(os.path.join(balm, "poses.txt")):
        out.append(("balm_os0", "balm_os0 (real)", None, balm, [], None))
    else:
        print(f"slam_suite.py: {balm} has no poses.txt: balm_os0 skipped", file=sys.stderr)
    kitti = os.path.join(data, "kitti_hdl64_seq16")
    if not os.path.isdir(kitti):
        print(f"slam_suite.py: {kitti} is absent: kitti_hdl64_seq16 skipped", file=sys.stderr)
    elif not os.path.isfile(kitti_reference):
        print(f"slam_suite.py: kitti_hdl64_seq16 skipped: no reference at {kitti_reference} "
              f"(bench/slam_peers.py kitti_hdl64_seq16 writes it)", file=sys.stderr)
    else:
        out.append(("kitti_hdl64_seq16", "kitti_hdl64_seq16 (real, against Open3D ICP)", None, kitti, [], kitti_reference))
    return out


def sim_folder(work, sim):
    return os.path.join(work, "sim", "_".join(a.lstrip("-") for a in sim).replace("/", "_"))


def run(cmd, log):
    with open(log, "w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed (exit {r.returncode}), see {log}")


def simulate(hmap, work, sim):
    folder = sim_folder(work, sim)
    if os.path.isfile(os.path.join(folder, "poses.txt")):
        return folder
    os.makedirs(os.path.dirname(folder), exist_ok=True)
    tmp = folder + ".partial"
    subprocess.run(["rm", "-rf", tmp], check=True)
    run([hmap, "simulate", *sim, "--out", tmp], folder + ".log")
    os.replace(tmp, folder)
    return folder


def runs_folder(work, extra):
    """Runs with other hmap slam arguments go to their own folder; the simulations are shared."""
    return os.path.join(work, "runs" + ("_" + re.sub(r"[^A-Za-z0-9.=_-]+", "_", "_".join(extra)) if extra else ""))


def slam_and_score(hmap, work, case, seq, extra):
    name, group, _, _, slam_args, reference = case
    out = os.path.join(runs_folder(work, extra), name)
    args = [a.replace("@", seq) for a in slam_args]
    start = time.monotonic()
    run([hmap, "slam", "--kitti", seq, *args, *extra, "--out", out], out + ".log")
    seconds = time.monotonic() - start
    r = subprocess.run([hmap, "eval", "traj", "--gt", reference or os.path.join(seq, "poses.txt"), "--est",
                        os.path.join(out, "poses.txt"), "--json"], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"hmap eval traj on {out}: {r.stderr.strip()}")
    d = json.loads(r.stdout)
    return {"name": name, "group": group, "rpe_pct": d["rpe_trans_pct"], "ate_origin_m": d["ate_rmse_origin_m"],
            "end_origin_m": d["end_error_origin_m"], "path_m": d["path_length_m"], "seconds": seconds}


FIGURES = (("rpe_pct", "RPE %", "{:.3f}"), ("ate_origin_m", "ATE first pose m", "{:.3f}"),
           ("end_origin_m", "end m", "{:.3f}"))


def groups_of(results):
    groups = {}
    for r in results:
        groups.setdefault(r["group"], []).append(r)
    return groups


def print_tables(results, baseline):
    base = {r["name"]: r for r in baseline["runs"]} if baseline else {}
    print("| run | path m | " + " | ".join(h for _, h, _ in FIGURES) + " | s |")
    print("| --- | --- | " + " | ".join("---" for _ in FIGURES) + " | --- |")
    for r in results:
        cells = []
        for key, _, fmt in FIGURES:
            cell = fmt.format(r[key])
            if r["name"] in base:
                cell += " (" + fmt.format(base[r["name"]][key]) + ")"
            cells.append(cell)
        print(f"| {r['name']} | {r['path_m']:.1f} | " + " | ".join(cells) + f" | {r['seconds']:.1f} |")
    print()
    print("| group | runs | RPE % mean | RPE % worst | ATE first pose m mean | ATE worst |")
    print("| --- | --- | --- | --- | --- | --- |")
    base_groups = groups_of(baseline["runs"]) if baseline else {}
    for group, rs in groups_of(results).items():
        def stats(runs):
            rpe = [r["rpe_pct"] for r in runs]
            ate = [r["ate_origin_m"] for r in runs]
            return sum(rpe) / len(rpe), max(rpe), sum(ate) / len(ate), max(ate)
        now = stats(rs)
        line = [f"{v:.3f}" for v in now]
        names = {r["name"] for r in rs}
        prev = [r for r in base_groups.get(group, []) if r["name"] in names]
        if len(prev) == len(rs):
            line = [f"{a:.3f} ({b:.3f})" for a, b in zip(now, stats(prev))]
        print(f"| {group} | {len(rs)} | " + " | ".join(line) + " |")
    if base:
        better = worse = 0
        for r in results:
            if r["name"] not in base:
                continue
            b = base[r["name"]]["rpe_pct"]
            better += r["rpe_pct"] < 0.97 * b
            worse += r["rpe_pct"] > 1.03 * b
        print(f"\nRPE against the baseline (in brackets), runs: {better} better and {worse} worse by more than 3 %, "
              f"the rest within 3 %.")


def main():
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        extra = argv[argv.index("--") + 1:]
        argv = argv[:argv.index("--")]
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hmap", default="build/bin/hmap")
    ap.add_argument("--data", default=os.environ.get("HMAP_DATA_DIR", "../shared/data"))
    ap.add_argument("--work", default="out/slam_suite")
    ap.add_argument("--seeds", type=int, default=4, help="noise seeds of the VLP-16 parking route (1-32)")
    ap.add_argument("--jobs", type=int, default=2, help="hmap processes at once (1-16)")
    ap.add_argument("--only", default="", help="runs whose name matches this regular expression")
    ap.add_argument("--kitti-reference", default="out/slam_peers/kitti_hdl64_seq16/open3d.txt",
                    help="Open3D ICP's poses of kitti_hdl64_seq16 (bench/slam_peers.py writes them)")
    ap.add_argument("--mount-yaw", type=float, default=0.0,
                    help="[deg] the simulated lidars mounted turned by this (hmap simulate --mount-yaw), so that the "
                         "scenes' walls are not parallel to the map's grid")
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--baseline", help="a --json file of an earlier run, shown in brackets")
    a = ap.parse_args(argv)
    if not 1 <= a.seeds <= 32:
        ap.error(f"--seeds {a.seeds}: must be 1 to 32")
    if not 1 <= a.jobs <= 16:
        ap.error(f"--jobs {a.jobs}: must be 1 to 16")
    if not -180.0 <= a.mount_yaw <= 180.0:
        ap.error(f"--mount-yaw {a.mount_yaw:g}: must be -180 to 180 deg")
    try:
        only = re.compile(a.only)
    except re.error as e:
        ap.error(f"--only {a.only!r}: {e}")
    if not os.access(a.hmap, os.X_OK):
        ap.error(f"--hmap {a.hmap}: not an executable (make tool builds it)")
    baseline = None
    if a.baseline:
        try:
            with open(a.baseline) as f:
                baseline = json.load(f)
            for r in baseline["runs"]:
                float(r["rpe_pct"]), float(r["ate_origin_m"]), float(r["end_origin_m"]), str(r["name"]), str(r["group"])
        except (OSError, ValueError, KeyError, TypeError) as e:
            ap.error(f"--baseline {a.baseline}: not a slam_suite.py --json file ({e})")
    todo = [c for c in cases(a.seeds, a.data, a.kitti_reference, a.mount_yaw) if only.search(c[0])]
    if not todo:
        ap.error(f"--only {a.only!r} matches no run")
    os.makedirs(runs_folder(a.work, extra), exist_ok=True)
    hmap = os.path.abspath(a.hmap)
    results = []
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as pool:
        # The simulations first (each once, however many runs share it), then the runs.
        sims = {tuple(c[2]) for c in todo if c[2] is not None}
        folders = dict(zip(sims, pool.map(lambda s: simulate(hmap, a.work, list(s)), sims)))
        jobs = [pool.submit(slam_and_score, hmap, a.work, c, c[3] or folders[tuple(c[2])], extra) for c in todo]
        for job in jobs:
            r = job.result()
            results.append(r)
            if sys.stderr.isatty():
                print(f"{r['name']}: RPE {r['rpe_pct']:.3f} %", file=sys.stderr)
    print(f"hmap slam {' '.join(extra) or '(defaults)'}: {len(results)} runs\n")
    print_tables(results, baseline)
    if a.json:
        os.makedirs(os.path.dirname(os.path.abspath(a.json)), exist_ok=True)
        tmp = a.json + ".tmp"
        with open(tmp, "w") as f:
            json.dump({"slam_args": extra, "runs": results}, f, indent=1)
        os.replace(tmp, a.json)


if __name__ == "__main__":
    try:
        main()
    except RuntimeError as e:
        sys.exit(f"slam_suite.py: {e}")
