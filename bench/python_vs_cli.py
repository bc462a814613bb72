#!/usr/bin/python3
"""Integration time per scan, Python (hmap.HybridMapper) against the CLI (`hmap map`), same scans,
same parameters (taken from the CLI's map), same map bytes.

  PYTHONPATH=build/python /usr/bin/python3 bench/python_vs_cli.py --hmap build/bin/hmap \\
      --kitti ../shared/data/balm_os0 --cell 0.2 [--scans N] [--rounds R]

Both sides time the integration calls only (the CLI's "Integration took X ms per scan"; here the
integrate() calls, the scans read beforehand): the difference is the binding's overhead. The best
of R rounds of each is reported, as the machine may be shared.
"""

import argparse
import pathlib
import re
import subprocess
import sys
import tempfile
import time

import hmap


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hmap", required=True, help="the hmap tool")
    ap.add_argument("--kitti", required=True, help="KITTI-layout folder (velodyne/*.bin, poses.txt)")
    ap.add_argument("--cell", type=float, default=0.2)
    ap.add_argument("--scans", type=int, default=0, help="first N scans (0: all)")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    data = pathlib.Path(a.kitti)
    scans = sorted((data / "velodyne").glob("*.bin"))
    if a.scans:
        scans = scans[: a.scans]
    with tempfile.TemporaryDirectory() as tmp:
        cli_map = pathlib.Path(tmp) / "cli.hmap"
        cli_ms = []
        for _ in range(a.rounds):
            out = subprocess.run([a.hmap, "map", "--kitti", str(data), "--scans", str(len(scans)), "--preset", "outdoor",
                                  "--cell", str(a.cell), "--out", str(cli_map)], check=True, capture_output=True, text=True).stdout
            cli_ms.append(float(re.search(r"Integration took ([0-9.]+) ms per scan", out).group(1)))
        params = hmap.Map.load(cli_map).params
        poses = hmap.io.read_poses(data / "poses.txt")
        clouds = [hmap.io.read_cloud(s) for s in scans]
        py_ms = []
        for _ in range(a.rounds):
            mapper = hmap.HybridMapper(params)
            t0 = time.perf_counter()
            for cloud, T in zip(clouds, poses):
                mapper.integrate(cloud, T)
            py_ms.append((time.perf_counter() - t0) * 1000.0 / len(clouds))
        py_map = pathlib.Path(tmp) / "py.hmap"
        mapper.map.save(py_map)
        same = py_map.read_bytes() == cli_map.read_bytes()
    cli, py = min(cli_ms), min(py_ms)
    print(f"{len(scans)} scans of {data.name}, cell {a.cell} m, best of {a.rounds}: CLI {cli:.1f} ms/scan, "
          f"Python {py:.1f} ms/scan ({100.0 * (py - cli) / cli:+.1f} %); same map bytes: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
