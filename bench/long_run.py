#!/usr/bin/env python3
"""Long runs: `hmap map` over the same place again and again, to show that memory stays bounded.

usage: long_run.py HMAP_BIN DATA_DIR [N ...]     (default N: 80 800 3200)

For each N, maps N scans of DATA_DIR/balm_os0 (its 80 scans cycled: scan k is scan k mod 80
with pose k mod 80, so every cycle maps the same building again) with the full hybrid map of
`hmap map` (HMAP, ground patches, 2D grid) at 0.1 m, and prints the wall time, the peak resident
memory of the process (getrusage of the child), the map file's size and the map's counts.
Memory bounded means: peak RSS at N = 3200 is that of N = 80 plus no more than the map's growth.
"""
import os
import re
import resource
import subprocess
import sys
import tempfile
import time


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    hmap, data = sys.argv[1], sys.argv[2]
    counts = [int(n) for n in sys.argv[3:]] or [80, 800, 3200]
    seq = os.path.join(data, "balm_os0")
    with open(os.path.join(seq, "poses.txt")) as f:
        poses = [line for line in f.read().splitlines() if line.strip()]
    scans = sorted(os.listdir(os.path.join(seq, "velodyne")))
    assert len(scans) == len(poses)
    print("| scans | wall [s] | ms/scan | peak RSS [MiB] | map file [KiB] | cells | HVoxels |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    with tempfile.TemporaryDirectory() as tmp:
        for n in counts:
            poses_path = os.path.join(tmp, "poses.txt")
            with open(poses_path, "w") as f:
                f.write("\n".join(poses[k % len(poses)] for k in range(n)) + "\n")
            files = [os.path.join(seq, "velodyne", scans[k % len(scans)]) for k in range(n)]
            out = os.path.join(tmp, "map.hmap")
            start = time.monotonic()
            proc = subprocess.Popen([hmap, "map", *files, "--poses", poses_path, "--preset", "outdoor",
                                     "--cell", "0.1", "--out", out],
                                    stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
            stdout = proc.stdout.read()
            _, status, usage = os.wait4(proc.pid, 0)
            wall = time.monotonic() - start
            if status != 0:
                sys.exit("hmap map failed for N = %d:\n%s" % (n, stdout))
            m = re.search(r"The map has (\d+) cells and (\d+) HVoxels", stdout)
            ms = re.search(r"Integration took ([0-9.]+) ms per scan", stdout)
            print("| %d | %.1f | %s | %.1f | %.0f | %s | %s |" % (
                n, wall, ms.group(1) if ms else "?", usage.ru_maxrss / 1024.0, os.path.getsize(out) / 1024.0,
                m.group(1) if m else "?", m.group(2) if m else "?"), flush=True)


if __name__ == "__main__":
    main()
