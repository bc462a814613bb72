"""examples/python/dask_build.py on a two-process distributed.LocalCluster: a simulated drive
split by tiles merges to the one-process map, HVoxel for HVoxel; split by scans it differs only
in the tiles both halves' scans reach."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import hmap
from conftest import REPO

pytest.importorskip("distributed", reason="Dask's distributed is not installed (Debian: python3-distributed)")

SCRIPT = REPO / "examples" / "python" / "dask_build.py"
MAX_RANGE = 8.0  # [m] short, so that the drive is many reaches long and most scans reach one part only


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """40 VLP-16 scans along the parking route (every 3rd frame, 60 m), as `hmap simulate` writes them."""
    seq = tmp_path_factory.mktemp("drive")
    rec = hmap.sim.simulate("parking", "vlp16", frames=40, stride=3, truth_spacing=2.0, seed=2)
    hmap.sim.write_sequence(seq, rec["scans"], rec["poses"], rec["times"])
    return seq


def one_process_map(seq):
    sequence = hmap.io.open_source(kitti=str(seq))
    params = hmap.params_for_scan(sequence.read(0)[0], max_range=MAX_RANGE)["params"]
    mapper = hmap.Mapper(params)
    for k in range(len(sequence)):
        points, T_map_sensor = sequence.read(k)[:2]
        mapper.integrate(points, T_map_sensor)
    return mapper.map, sequence.poses


def run(seq, out, *args):
    r = subprocess.run([sys.executable, str(SCRIPT), "--kitti", seq, "--out", out / "map.hmap", "--workers", "2",
                        "--max-range", str(MAX_RANGE), "--json", out / "figures.json", *map(str, args)],
                       capture_output=True, text=True, env=dict(os.environ), timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout, json.loads((out / "figures.json").read_text()), hmap.Map.load(out / "map.hmap")


def test_split_by_tiles_equals_the_one_process_map(drive, tmp_path):
    out, figures, merged = run(drive, tmp_path, "--check")
    one, poses = one_process_map(drive)
    assert len(poses) == 40
    assert figures["workers"] == 2 and figures["parts"] == 2 and len(figures["merges"]) == 1
    assert len({p["pid"] for p in figures["part"]}) == 2  # two worker processes built the parts
    # Each tile is owned once; the scans near the border are integrated by both parts, the others once.
    assert sum(p["tiles"] for p in figures["part"]) == merged.stats()["tiles"] == one.stats()["tiles"]
    assert 40 < figures["scans_integrated"] < 2 * 40
    assert one.stats()["hvoxels"] > 5000
    np.testing.assert_array_equal(merged.hvoxels(), one.hvoxels())
    assert figures["check"]["equal"] and "equal to the one-process map" in out


def test_split_by_scans_differs_only_where_both_halves_reach(drive, tmp_path):
    out, figures, merged = run(drive, tmp_path, "--split", "scans", "--check")
    one, poses = one_process_map(drive)
    assert figures["scans_integrated"] == 40 and figures["parts"] == 2
    a, b = one.hvoxels(), merged.hvoxels()

    def columns(hv):
        cols = {}
        for row in hv:
            cols.setdefault((int(row["i"]), int(row["j"])), []).append(tuple(row)[2:])
        return cols

    ca, cb = columns(a), columns(b)
    differ = [k for k in ca.keys() | cb.keys() if ca.get(k) != cb.get(k)]
    assert differ, "the halves overlap, so a merge cannot carve what the other half's rays freed"
    assert figures["check"]["columns_differ"] == len(differ)
    assert f"differs from the one-process map in {len(differ)} of {len(ca)} columns" in out
    # Every differing column lies within reach of a sensor of each half (the first 20 scans, the last 20).
    cell = one.cell_size
    reach = MAX_RANGE + 2 * cell
    first, second = poses[:20, :2, 3], poses[20:, :2, 3]
    for i, j in differ:
        centre = (np.array([i, j]) + 0.5) * cell
        assert np.min(np.linalg.norm(first - centre, axis=1)) < reach
        assert np.min(np.linalg.norm(second - centre, axis=1)) < reach
    assert len(differ) < len(ca) / 2


def test_bad_input_is_one_line_and_exit_code_2(tmp_path):
    r = subprocess.run([sys.executable, str(SCRIPT), "--kitti", tmp_path / "nowhere", "--out", tmp_path / "m.hmap"],
                       capture_output=True, text=True, env=dict(os.environ))
    assert r.returncode == 2 and r.stderr.strip() == f"dask_build: --kitti {tmp_path / 'nowhere'}: no such folder"
    r = subprocess.run([sys.executable, str(SCRIPT), "--kitti", tmp_path, "--out", tmp_path / "m.ply"],
                       capture_output=True, text=True, env=dict(os.environ))
    assert r.returncode == 2 and "expected a .hmap file" in r.stderr
    (tmp_path / "velodyne").mkdir()
    r = subprocess.run([sys.executable, str(SCRIPT), "--kitti", tmp_path, "--out", tmp_path / "m.hmap"],
                       capture_output=True, text=True, env=dict(os.environ))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp_path / "m.hmap").exists()
