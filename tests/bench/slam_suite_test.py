#!/usr/bin/env python3
"""bench/slam_suite.py on its smallest route (the office, 60 VLP-16 frames): the figures it reports
are `hmap eval traj`'s on the run it made, a simulation is made once and reused, the baseline's
brackets and counts follow the figures, `hmap slam` arguments after `--` reach the runs, and bad
arguments end with exit 2 and a line naming them.

usage: slam_suite_test.py --hmap BIN --source REPO
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print(f"FAILED: {what}", file=sys.stderr)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hmap", required=True)
    ap.add_argument("--source", required=True)
    a = ap.parse_args()
    suite = os.path.join(a.source, "bench", "slam_suite.py")
    with tempfile.TemporaryDirectory() as tmp:
        work = os.path.join(tmp, "work")
        # No data folder: the real sets are skipped with a message, the simulated ones run.
        base = [sys.executable, suite, "--hmap", a.hmap, "--data", os.path.join(tmp, "no-data"), "--work", work,
                "--only", "^office-vlp16$"]

        def suite_run(*args):
            return subprocess.run([*base, *args], capture_output=True, text=True)

        first_json = os.path.join(tmp, "first.json")
        r = suite_run("--json", first_json)
        check(r.returncode == 0, f"a run of office-vlp16 exits 0 (got {r.returncode}: {r.stderr[-500:]})")
        if r.returncode != 0:
            return
        check("balm_os0 skipped" in r.stderr and "kitti_hdl64_seq16 is absent" in r.stderr,
              f"the missing real sets are named on stderr: {r.stderr!r}")
        with open(first_json) as f:
            first = json.load(f)
        check(len(first["runs"]) == 1 and first["runs"][0]["name"] == "office-vlp16", f"one run: {first['runs']}")
        run = first["runs"][0]
        sim = os.path.join(work, "sim", "scene_office_sensor_vlp16_frames_60")
        est = os.path.join(work, "runs", "office-vlp16", "poses.txt")
        # Its figures are hmap eval traj's on the poses it wrote, against the simulation's truth.
        e = json.loads(subprocess.run([a.hmap, "eval", "traj", "--gt", os.path.join(sim, "poses.txt"), "--est", est,
                                       "--json"], check=True, capture_output=True, text=True).stdout)
        check(run["rpe_pct"] == e["rpe_trans_pct"] and run["ate_origin_m"] == e["ate_rmse_origin_m"] and
              run["end_origin_m"] == e["end_error_origin_m"], f"the figures are eval traj's: {run} against {e}")
        check(abs(run["path_m"] - 3.0) < 0.1, f"the office route is 3 m long (60 frames at 5 cm): {run['path_m']}")
        check(f"| office-vlp16 | 3.0 | {run['rpe_pct']:.3f} |" in r.stdout, f"the table holds the run: {r.stdout}")

        # Again, against the first as the baseline: the simulation is reused (its log not rewritten),
        # the same binary gives the same figures, so every run is within 3 %.
        log = sim + ".log"
        stamp = os.stat(log).st_mtime_ns
        r = suite_run("--baseline", first_json)
        check(r.returncode == 0, f"the second run exits 0: {r.stderr[-500:]}")
        check(os.stat(log).st_mtime_ns == stamp, "the simulation is made once and reused")
        rpe = f"{run['rpe_pct']:.3f}"
        check(f"| {rpe} ({rpe}) |" in r.stdout, f"the baseline's figure in brackets: {r.stdout}")
        check("runs: 0 better and 0 worse" in r.stdout, f"no change against itself: {r.stdout}")

        # A baseline whose RPE was twice as large counts this run better; half, worse.
        for factor, expect in ((2.0, "runs: 1 better and 0 worse"), (0.5, "runs: 0 better and 1 worse")):
            changed = json.loads(json.dumps(first))
            changed["runs"][0]["rpe_pct"] *= factor
            path = os.path.join(tmp, f"baseline_{factor}.json")
            with open(path, "w") as f:
                json.dump(changed, f)
            r = suite_run("--baseline", path)
            check(expect in r.stdout, f"a baseline RPE x{factor} gives '{expect}': {r.stdout}")

        # hmap slam's arguments after -- reach the run, which goes to a folder of its own.
        r = suite_run("--json", os.path.join(tmp, "walls.json"), "--", "--set", "slam.wall_refine=1")
        check(r.returncode == 0, f"a run with -- --set exits 0: {r.stderr[-500:]}")
        walls = os.path.join(work, "runs_--set_slam.wall_refine=1", "office-vlp16")
        check(os.path.isfile(os.path.join(walls, "poses.txt")), "the run with other arguments has its own folder")
        with open(os.path.join(walls, "matches.csv")) as f:
            header = f.readline().split(",")
            applied = sum(line.split(",")[header.index("wall_refined")] == "1" for line in f)
        check(applied > 0, "the walls ran: --set slam.wall_refine=1 reached hmap slam")
        with open(os.path.join(tmp, "walls.json")) as f:
            check(json.load(f)["slam_args"] == ["--set", "slam.wall_refine=1"], "the JSON records the arguments")

        # --mount-yaw turns the simulated lidar: a run of its own, simulated with hmap simulate --mount-yaw.
        r = subprocess.run([sys.executable, suite, "--hmap", a.hmap, "--data", os.path.join(tmp, "no-data"), "--work",
                            work, "--only", "^office-vlp16-turned20$", "--mount-yaw", "20"], capture_output=True, text=True)
        check(r.returncode == 0, f"a turned run exits 0: {r.stderr[-500:]}")
        turned_log = os.path.join(work, "sim", "scene_office_sensor_vlp16_frames_60_mount-yaw_20.log")
        check(os.path.isfile(turned_log) and "the sensor turned 20 deg" in open(turned_log).read(),
              "the turned route is hmap simulate --mount-yaw 20")
        check("| office-vlp16-turned20 | 3.0 |" in r.stdout, f"the turned run has its own name: {r.stdout}")

        # Bad arguments: exit 2, one line naming the argument.
        bad_baseline = os.path.join(tmp, "bad.json")
        with open(bad_baseline, "w") as f:
            f.write("{not json")
        for args, named in ((["--seeds", "0"], "--seeds 0"), (["--jobs", "99"], "--jobs 99"),
                            (["--only", "("], "--only '('"), (["--mount-yaw", "400"], "--mount-yaw 400"), (["--only", "nothing-matches"], "matches no run"),
                            (["--hmap", os.path.join(tmp, "absent")], "not an executable"),
                            (["--baseline", bad_baseline], f"--baseline {bad_baseline}")):
            r = subprocess.run([sys.executable, suite, "--hmap", a.hmap, "--work", work, *args],
                               capture_output=True, text=True)
            check(r.returncode == 2 and named in r.stderr, f"{args}: exit 2 naming it (got {r.returncode}: {r.stderr!r})")


if __name__ == "__main__":
    main()
    sys.exit(1 if failures else 0)
