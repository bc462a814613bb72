"""hmap.merge_maps / hmap.align_maps: two sessions' maps made one, as `hmap merge` makes them."""

import math
import subprocess

import numpy as np
import pytest

import hmap
from conftest import cli_or_skip


def yard_points(rng):
    """A yard in the world frame: a floor, three walls of different heights and two pillars."""
    floor = np.column_stack([rng.uniform(-9, 9, 20000), rng.uniform(-9, 9, 20000), np.zeros(20000)])
    parts = [floor]
    for x0, y0, x1, y1, h in ((8, -8, 8, 8, 3.0), (-8, 8, 8, 8, 2.0), (-8, -8, -8, 2, 4.0)):
        t = rng.uniform(0, 1, 6000)
        parts.append(np.column_stack([x0 + t * (x1 - x0), y0 + t * (y1 - y0), rng.uniform(0, h, 6000)]))
    for cx, cy in ((2.0, 3.0), (-3.0, -4.0)):
        a = rng.uniform(0, 2 * math.pi, 3000)
        parts.append(np.column_stack([cx + 0.3 * np.cos(a), cy + 0.3 * np.sin(a), rng.uniform(0, 2.5, 3000)]))
    return np.vstack(parts)


def pose(x, y, z, yaw):
    T = np.eye(4)
    T[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
    T[:3, 3] = (x, y, z)
    return T


def session(params, world, T_frame, sensor_at):
    """A HybridMapper's map of `world` seen from `sensor_at` (world frame), its poses written in a
    frame T_frame away (T_frame @ T)."""
    mapper = hmap.HybridMapper(params)
    for T in sensor_at:
        pts = (world - T[:3, 3]) @ T[:3, :3]  # into the sensor frame
        mapper.integrate(pts.astype(np.float32), T_frame @ T)
    return mapper.map


@pytest.fixture
def yard_params():
    p = hmap.Params("outdoor")
    p.map.cell_size = 0.2
    p.map.max_range = 20.0
    return p


def test_merge_with_an_empty_map_and_a_whole_cell_shift(yard_params):
    world = yard_points(np.random.default_rng(1))
    a = session(yard_params, world, np.eye(4), [pose(0, 0, 1.5, 0)])
    empty = hmap.HybridMapper(yard_params).map
    same = hmap.merge_maps(a, empty)
    assert same.stats()["hvoxels"] == a.stats()["hvoxels"]
    np.testing.assert_array_equal(same.hvoxels(), a.hvoxels())
    moved = hmap.merge_maps(empty, a, shift=(0.6, -0.4, 0.25, 0.0))  # 3 and -2 cells
    ha, hm = a.hvoxels(), moved.hvoxels()
    np.testing.assert_array_equal(hm["i"], ha["i"] + 3)
    np.testing.assert_array_equal(hm["j"], ha["j"] - 2)
    np.testing.assert_allclose(hm["z_min"], ha["z_min"] + 0.25, atol=1e-6)
    np.testing.assert_array_equal(hm["count"], ha["count"])


def test_align_recovers_a_known_shift_and_matches_the_cli(yard_params, tmp_path):
    world = yard_points(np.random.default_rng(2))
    a = session(yard_params, world, np.eye(4), [pose(0, 0, 1.5, 0), pose(-3, 2, 1.5, 0.5)])
    S = pose(0.8, -0.5, 0.1, math.radians(9.0))
    b = session(yard_params, world, S, [pose(2, -1, 1.5, 1.0), pose(4, 3, 1.5, -0.7)])
    want = np.linalg.inv(S)
    r = hmap.align_maps(a, b, search=2.0, search_yaw=0.3)
    x, y, z, yaw = r["shift"]
    assert x == pytest.approx(want[0, 3], abs=0.05)
    assert y == pytest.approx(want[1, 3], abs=0.05)
    assert z == pytest.approx(want[2, 3], abs=0.05)
    assert yaw == pytest.approx(math.radians(-9.0), abs=math.radians(0.3))
    assert r["columns_used"] > 1000 and r["converged"]
    merged = hmap.merge_maps(a, b, shift=r["shift"])
    assert merged.grid() is not None and len(merged.ground_patches()["half_size"]) >= len(a.ground_patches()["half_size"])
    # The CLI on the same two files merges to the same map.
    cli = cli_or_skip()
    a.save(tmp_path / "a.hmap")
    b.save(tmp_path / "b.hmap")
    out = subprocess.run([str(cli), "merge", str(tmp_path / "a.hmap"), str(tmp_path / "b.hmap"), "--shift",
                          *(f"{v!r}" for v in (x, y, z, math.degrees(yaw))), "--out", str(tmp_path / "m.hmap")],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    cli_map = hmap.Map.load(tmp_path / "m.hmap")
    assert cli_map.stats()["hvoxels"] == merged.stats()["hvoxels"]
    np.testing.assert_array_equal(cli_map.hvoxels(), merged.hvoxels())


def test_bad_merges_raise_the_librarys_message(yard_params):
    world = yard_points(np.random.default_rng(3))
    a = session(yard_params, world, np.eye(4), [pose(0, 0, 1.5, 0)])
    fine = hmap.Params("outdoor")
    fine.map.cell_size = 0.1
    b = session(fine, world, np.eye(4), [pose(0, 0, 1.5, 0)])
    with pytest.raises(hmap.Error, match="cells differ"):
        hmap.merge_maps(a, b)
    with pytest.raises(hmap.Error, match="finite"):
        hmap.merge_maps(a, a, shift=(math.nan, 0, 0, 0))
    with pytest.raises(hmap.Error, match="no column"):
        hmap.align_maps(a, a, guess=(500.0, 0, 0, 0))
    # One live mapper's map on both sides: its lock is taken once (taken twice, it never returned).
    twice = hmap.merge_maps(a, a)
    assert twice.stats()["cells"] == a.stats()["cells"]


def test_crop_map_keeps_the_tile_range_exactly_and_parts_merge_back(yard_params):
    world = yard_points(np.random.default_rng(3))
    m = session(yard_params, world, np.eye(4), [pose(-3, 0, 1.5, 0), pose(3, 1, 1.5, 0.4)])
    hv = m.hvoxels()
    tile_i = hv["i"] // hmap.TILE_CELLS
    assert hmap.TILE_CELLS == 8 and tile_i.min() < 0 <= tile_i.max()
    west = hmap.crop_map(m, (-(1 << 27), -(1 << 27), 0, 1 << 27))
    east = hmap.crop_map(m, tiles=(0, -(1 << 27), 1 << 27, 1 << 27))
    np.testing.assert_array_equal(west.hvoxels(), hv[tile_i < 0])
    np.testing.assert_array_equal(east.hvoxels(), hv[tile_i >= 0])
    assert west.grid() is None and west.stats()["ground_patches"] == 0  # the HMAP alone
    assert west.cell_size == m.cell_size
    np.testing.assert_array_equal(hmap.merge_maps(west, east).hvoxels(), hv)
    assert hmap.crop_map(m, (5, 5, 5, 9)).stats()["hvoxels"] == 0
    with pytest.raises(hmap.Error, match="ends before it begins"):
        hmap.crop_map(m, (1, 0, 0, 1))
