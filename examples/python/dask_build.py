#!/usr/bin/env python3
"""Build an HMAP on a Dask cluster: a sequence with known poses split by tiles across workers,
each part built from the scans that reach its tiles and cut to them, the parts merged by tile.

    PYTHONPATH=build/python python3 examples/python/dask_build.py --kitti SEQ --workers 2 --out map.hmap
    PYTHONPATH=build/python python3 examples/python/dask_build.py --kitti SEQ --scheduler tcp://host:8786 --out map.hmap

Without --scheduler a distributed.LocalCluster of --workers processes (one thread each) runs the
parts; with it, the same code runs on that cluster, whose workers must import the same `hmap`
package and read SEQ at the same path (a shared file system): only the scan indices, the
parameters and the sub-maps (.hmap bytes, compressed) travel.

--split tiles (the default) owns each tile in exactly one part, a strip of tiles across the
route's longer axis holding about as many scans as the others; a part integrates every scan whose
sensor is within max_range of its strip (the scans near a border are integrated by both sides)
and keeps only its strip (hmap.crop_map). A column changes only under the scans that reach it,
so the merged map equals the one-process map, HVoxel for HVoxel. --split scans gives each part a
run of consecutive scans instead and merges their whole maps: no scan is integrated twice, but
where two parts saw the same place one part's free space does not carve the other's HVoxels and
III-D unites HVoxels in another order, so those tiles differ (--check counts them; docs/SCALE.md).
The result is the HMAP alone: the ground tree and 2D grid of `hmap map` carry state along the
whole run and are not built in parts.
"""

import argparse
import json
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

import hmap

# Tile keys are kept within +-2^27 (cell keys within +-2^30): an open end of a strip.
FAR = 1 << 27


def map_bytes(m):
    """A map as the bytes of its .hmap file (compressed, checksummed): how sub-maps travel."""
    with tempfile.TemporaryDirectory() as d:
        path = pathlib.Path(d) / "part.hmap"
        m.save(path)
        return path.read_bytes()


def map_of(data):
    with tempfile.TemporaryDirectory() as d:
        path = pathlib.Path(d) / "part.hmap"
        path.write_bytes(data)
        return hmap.Map.load(path)


def params_of(values):
    p = hmap.Params("outdoor")
    p.update(values)
    return p


def build_part(kitti, indices, param_values, tiles):
    """On a worker: integrate scans `indices` of the KITTI folder in order, then keep `tiles`
    (i_begin, j_begin, i_end, j_end) of the map, or all of it for None."""
    wall, cpu = time.perf_counter(), time.process_time()
    sequence = hmap.io.open_source(kitti=kitti)
    mapper = hmap.Mapper(params_of(param_values))
    read = 0.0
    for k in indices:
        t = time.perf_counter()
        points, T_map_sensor = sequence.read(int(k))[:2]
        read += time.perf_counter() - t
        mapper.integrate(points, T_map_sensor)
    built = mapper.map
    part = built if tiles is None else hmap.crop_map(built, tiles)
    data = map_bytes(part)
    return data, {"scans": len(indices), "tiles_built": built.stats()["tiles"], "tiles": part.stats()["tiles"],
                  "hvoxels": part.stats()["hvoxels"], "bytes": len(data), "read_s": read,
                  "wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu, "pid": os.getpid()}


def merge_pair(a, b):
    """On a worker: two sub-maps merged by tile (hmap.merge_maps), as .hmap bytes."""
    wall, cpu = time.perf_counter(), time.process_time()
    data = map_bytes(hmap.merge_maps(map_of(a[0]), map_of(b[0])))
    cost = {"wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu, "bytes_in": len(a[0]) + len(b[0])}
    return data, {"merges": a[1]["merges"] + b[1]["merges"] + [cost]}


def as_merged(result):
    return result[0], {"merges": []}


def plan_tiles(positions, parts, edge, reach):
    """At most `parts` strips of tiles across one axis, each part: (tile range, the indices of every
    scan whose sensor is within `reach` of its strip). The cuts are placed so that the largest
    part, its border scans included, is as small as it can be; the axis with the smaller one wins."""
    best = None
    for axis in (0, 1):
        coord = positions[:, axis]
        ordered = np.sort(coord)

        def count(lo, hi):
            return int(np.searchsorted(ordered, hi * edge + reach) - np.searchsorted(ordered, lo * edge - reach))

        candidates = np.unique(np.floor(coord / edge).astype(np.int64))[1:]  # a strip may end before these

        def strips(target):
            """Greedy from the low end, each strip as long as it holds at most `target` scans."""
            bounds = [-FAR]
            while count(bounds[-1], FAR) > target:
                fits = [c for c in candidates if c > bounds[-1] and count(bounds[-1], c) <= target]
                if not fits or len(bounds) > parts:
                    return None
                bounds.append(max(fits))
            return bounds + [FAR] if len(bounds) <= parts else None

        lo, hi = -(-len(coord) // parts), len(coord)   # the smallest largest part that fits
        while lo < hi:
            mid = (lo + hi) // 2
            lo, hi = (lo, mid) if strips(mid) else (mid + 1, hi)
        if best is None or lo < best[0]:
            best = (lo, axis, strips(lo), coord)
    _, axis, bounds, coord = best
    plan = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        near = (coord >= lo * edge - reach) & (coord < hi * edge + reach)
        tiles = (lo, -FAR, hi, FAR) if axis == 0 else (-FAR, lo, FAR, hi)
        plan.append((tiles, np.flatnonzero(near).tolist()))
    return plan, "xy"[axis]


def plan_scans(count, parts):
    return [(None, chunk.tolist()) for chunk in np.array_split(np.arange(count), parts) if len(chunk)]


def compare(a, b):
    """Columns and tiles where two maps differ (HVoxel for HVoxel), as counts."""
    def columns(m):
        hv = m.hvoxels()   # sorted by cell, then height
        cells = np.stack([hv["i"], hv["j"]], axis=1)
        starts = np.flatnonzero(np.r_[True, np.any(cells[1:] != cells[:-1], axis=1)])
        ends = np.r_[starts[1:], len(hv)]
        return {(int(cells[s, 0]), int(cells[s, 1])): hv[s:e].tobytes() for s, e in zip(starts, ends)}
    ca, cb = columns(a), columns(b)
    differ = {k for k in ca.keys() | cb.keys() if ca.get(k) != cb.get(k)}
    tiles = {(i // hmap.TILE_CELLS, j // hmap.TILE_CELLS) for i, j in differ}
    return {"columns": len(ca), "columns_differ": len(differ), "only_in_one": len(ca.keys() ^ cb.keys()),
            "tiles_differ": len(tiles), "equal": not differ}


def reduce_tree(client, futures):
    """Pairwise merges on the workers until one map is left: log2(parts) rounds."""
    level = [client.submit(as_merged, f) for f in futures]
    while len(level) > 1:
        pairs = [client.submit(merge_pair, level[k], level[k + 1]) for k in range(0, len(level) - 1, 2)]
        level = pairs + ([level[-1]] if len(level) % 2 else [])
    return level[0]


def fail(message):
    print(f"dask_build: {message}", file=sys.stderr)
    sys.exit(2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kitti", type=pathlib.Path, required=True, help="KITTI-style folder: velodyne/, poses.txt")
    ap.add_argument("--out", type=pathlib.Path, required=True, help="the merged map (.hmap)")
    ap.add_argument("--scheduler", help="address of a running Dask scheduler (tcp://host:8786); else a LocalCluster")
    ap.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (default 2)")
    ap.add_argument("--parts", type=int, default=0, help="sub-maps (default: one per worker)")
    ap.add_argument("--split", choices=("tiles", "scans"), default="tiles")
    ap.add_argument("--scans", type=int, default=0, help="the first N scans (0: all)")
    ap.add_argument("--preset", choices=hmap.Params.presets(), help="default: chosen from the first scan, as `hmap map`")
    ap.add_argument("--cell", type=float, help="map.cell_size [m]")
    ap.add_argument("--max-range", type=float, help="map.max_range [m]: the reach of a scan, so the width of a border")
    ap.add_argument("--check", action="store_true",
                    help="also build the map in this process and compare, HVoxel for HVoxel")
    ap.add_argument("--json", type=pathlib.Path, help="write the figures there")
    a = ap.parse_args()
    if a.workers < 1 or a.parts < 0 or a.scans < 0:
        fail("--workers must be at least 1, --parts and --scans at least 0")
    if a.out.suffix != ".hmap":
        fail(f"--out {a.out}: expected a .hmap file")
    if not a.kitti.is_dir():
        fail(f"--kitti {a.kitti}: no such folder")
    try:
        import distributed
    except ImportError:
        fail("needs Dask's distributed scheduler (Debian: apt-get install python3-dask python3-distributed)")

    kitti = str(a.kitti.resolve())
    try:
        sequence = hmap.io.open_source(kitti=kitti, max_scans=a.scans or None)
        poses = sequence.poses
        if poses is None or len(poses) == 0:
            fail(f"--kitti {a.kitti}: no poses; the scans are split by where they were taken")
        first = sequence.read(0)[0]
        chosen = hmap.params_for_scan(first, a.preset, cell_size=a.cell, max_range=a.max_range)
    except hmap.Error as e:
        fail(str(e))
    params = chosen["params"]
    values = {name: params.get(name) for name in hmap.Params.names()}
    cell, max_range = params.get("map.cell_size"), params.get("map.max_range")
    edge = hmap.TILE_CELLS * cell

    start = time.perf_counter()
    if a.scheduler:
        client = distributed.Client(a.scheduler)
        where = f"scheduler {a.scheduler}"
    else:
        cluster = distributed.LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True,
                                           dashboard_address=None)
        client = distributed.Client(cluster)
        where = f"LocalCluster of {a.workers} processes"
    workers = len(client.scheduler_info()["workers"])
    cluster_s = time.perf_counter() - start
    parts = a.parts or max(1, workers)
    # A scan reaches the cells within max_range of its sensor; two cells more for the keys' rounding.
    if a.split == "tiles":
        plan, axis = plan_tiles(poses[:, :2, 3], parts, edge, max_range + 2 * cell)
    else:
        plan, axis = plan_scans(len(poses), parts), None

    with client:
        t = time.perf_counter()
        futures = [client.submit(build_part, kitti, indices, values, tiles, pure=False) for tiles, indices in plan]
        merged = reduce_tree(client, futures)
        results = client.gather(futures)
        build_s = time.perf_counter() - t
        data, merge_info = merged.result()
        total_s = time.perf_counter() - t
    if a.scheduler is None:
        cluster.close()

    a.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = a.out.with_name(a.out.name + ".part")
    tmp.write_bytes(data)
    os.replace(tmp, a.out)
    result = hmap.Map.load(a.out)   # the bytes checked as any .hmap file is
    stats = result.stats()

    scans_done = sum(r[1]["scans"] for r in results)
    merges = merge_info["merges"]
    figures = {
        "where": where, "workers": workers, "split": a.split, "axis": axis, "parts": len(plan), "scans": len(poses),
        "scans_integrated": scans_done, "preset": chosen["preset"], "cell_size": cell, "max_range": max_range,
        "cluster_start_s": cluster_s, "parts_done_s": build_s, "total_s": total_s,
        "part": [r[1] for r in results], "merges": merges,
        "merge_wall_s": sum(m["wall_s"] for m in merges), "merge_cpu_s": sum(m["cpu_s"] for m in merges),
        "transferred_bytes": sum(r[1]["bytes"] for r in results) + sum(m["bytes_in"] for m in merges),
        "tiles": stats["tiles"], "hvoxels": stats["hvoxels"], "out_bytes": len(data),
    }
    print(f"{len(poses)} scans on {where} ({workers} workers), split by {a.split}"
          + (f" along {axis}" if axis else "") + f": {len(plan)} parts, {scans_done} scans integrated "
          f"({scans_done / len(poses):.2f} per scan); cluster up in {cluster_s:.1f} s")
    for k, (_, r) in enumerate(results):
        print(f"  part {k}: {r['scans']} scans, {r['tiles']} tiles kept of {r['tiles_built']} built, "
              f"{r['hvoxels']} HVoxels, {r['bytes'] / 1024:.0f} KiB; {r['wall_s']:.2f} s wall, {r['cpu_s']:.2f} s CPU "
              f"({r['read_s']:.2f} s reading), worker pid {r['pid']}")
    print(f"  merge: {len(merges)} merges by tile, {figures['merge_wall_s']:.2f} s wall, {figures['merge_cpu_s']:.2f} s CPU; "
          f"{figures['transferred_bytes'] / 1024:.0f} KiB of sub-maps moved")
    print(f"{stats['tiles']} tiles, {stats['hvoxels']} HVoxels in {total_s:.2f} s (parts and merge); wrote {a.out}")

    if a.check:
        t, cpu = time.perf_counter(), time.process_time()
        one = hmap.Mapper(params)
        for k in range(len(poses)):
            points, T_map_sensor = sequence.read(k)[:2]
            one.integrate(points, T_map_sensor)
        figures["one_process_s"] = time.perf_counter() - t
        figures["one_process_cpu_s"] = time.process_time() - cpu
        figures["check"] = compare(one.map, result)
        c = figures["check"]
        if c["equal"]:
            print(f"equal to the one-process map ({c['columns']} columns; built here in {figures['one_process_s']:.2f} s, "
                  f"{figures['one_process_cpu_s']:.2f} s CPU)")
        else:
            print(f"differs from the one-process map in {c['columns_differ']} of {c['columns']} columns "
                  f"({c['only_in_one']} held by one map only), {c['tiles_differ']} of {stats['tiles']} tiles")
    if a.json:
        a.json.write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
