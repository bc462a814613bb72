"""hmap.pvox: hand-computed probabilities, the .pvox file equal to `hmap pvox`'s, bad input."""

import math
import subprocess

import numpy as np
import pytest

import hmap
from conftest import cli_or_skip



def p_of(hits, misses, edge, variance=100e-6, lo=-2.0, hi=3.5, miss=0.4):
    """The relaxed logit of voxel_map.hpp, by hand."""
    logit = hits * math.log(1.0 + edge * edge / (2.0 * variance)) - misses * miss
    return 1.0 / (1.0 + math.exp(-min(max(logit, lo), hi)))


def test_hits_hand_computed():
    m = hmap.pvox.VoxelMap(0.01)                          # e^2 / (2 sigma^2) = 0.5: l_hit = ln 1.5
    pts = np.array([[0.0155, 0.0255, 0.0355]] * 2 + [[-0.0045, 0.0, 0.0]], dtype=np.float32)
    stats = m.insert(pts, np.eye(4))
    assert stats == {"hits": 3, "rejected": 0, "misses": 0}
    assert m.voxel_count == 2
    q = np.array([[0.011, 0.021, 0.031], [-0.001, 0.009, 0.001], [5.0, 5.0, 5.0]])
    np.testing.assert_allclose(m.probability(q), [p_of(2, 0, 0.01), p_of(1, 0, 0.01), 0.5], rtol=1e-12)
    v = m.voxels()                                        # sorted by key
    assert [(r["i"], r["j"], r["k"]) for r in v] == [(-1, 0, 0), (1, 2, 3)]
    assert v["hits"].tolist() == [1, 2]
    np.testing.assert_allclose(v[1][["x", "y", "z"]].tolist(), [0.015, 0.025, 0.035], atol=1e-12)
    assert len(m.occupied(p_of(1, 0, 0.01) + 1e-9)) == 1  # only the voxel with two hits is above
    # A pose moves the points: the same point 1 m along x lands in voxel i = 101.
    T = np.eye(4)
    T[0, 3] = 1.0
    m.insert(pts[:1], T)
    assert m.probability(np.array([[1.0155, 0.0255, 0.0355]]))[0] == pytest.approx(p_of(1, 0, 0.01))


def test_rays_count_misses_hand_computed():
    m = hmap.pvox.VoxelMap(0.01)
    stats = m.insert(np.array([[0.055, 0.005, 0.005]]), np.eye(4), free_space="rays")
    assert stats["hits"] == 1 and stats["misses"] == 5     # voxels i = 0..4 before the end point's i = 5
    np.testing.assert_allclose(m.probability(np.array([[0.025, 0.005, 0.005]])), [p_of(0, 1, 0.01)], rtol=1e-12)
    stats = m.insert(np.array([[0.05, 0.0, 0.0]]), np.eye(4), min_range=0.1)
    assert stats == {"hits": 0, "rejected": 1, "misses": 0}


def test_field_and_save_load_round_trip(tmp_path):
    m = hmap.pvox.VoxelMap(0.1)
    g = np.stack(np.meshgrid(np.arange(-10, 10) * 0.1 + 0.05, np.arange(-10, 10) * 0.1 + 0.05, [0.05],
                             indexing="ij"), axis=-1).reshape(-1, 3)
    m.insert(g, np.eye(4))
    p, grad = m.field(np.array([[0.0, 0.0, 0.05], [0.0, 0.0, 0.1]]))
    assert p[0] == pytest.approx(p_of(1, 0, 0.1))        # at a voxel centre's height, inside the plane
    assert p[1] < p[0] and grad[1, 2] < 0.0              # p falls off above the plane
    m.save(tmp_path / "plane.pvox")
    back = hmap.pvox.VoxelMap.load(tmp_path / "plane.pvox")
    assert back.edge == m.edge and back.voxel_count == m.voxel_count == 400
    np.testing.assert_array_equal(back.voxels()[["i", "j", "k", "hits", "misses"]], m.voxels()[["i", "j", "k", "hits", "misses"]])
    assert back.voxels_csv() == m.voxels_csv()


def test_mapper_equals_the_cli(tmp_path):
    cli = cli_or_skip()
    seq, out = tmp_path / "seq", tmp_path / "out"
    subprocess.run([str(cli), "simulate", "--scene", "boxes", "--sensor", "utm30lx-tilt", "--frames", "3", "--stride", "5",
                    "--truth-spacing", "0.5", "--out", str(seq)], check=True, capture_output=True)
    subprocess.run([str(cli), "pvox", "--kitti", str(seq), "--measure", "poses", "--out", str(out)], check=True,
                   capture_output=True)
    mapper = hmap.pvox.Mapper()                          # `hmap pvox`'s defaults
    previous = None
    for points, T, _ in hmap.io.kitti_sequence(seq):
        motion = T if previous is None else np.linalg.inv(previous) @ T  # the commands: the poses' motions
        r = mapper.add_scan(points, motion, T[:2, 3])    # --measure poses
        previous = T
        np.testing.assert_allclose(r["T_map_sensor"][:2, 3], T[:2, 3], atol=0.01)
        assert r["insert"]["hits"] == len(points)
    assert mapper.scans == 3
    mapper.map.save(tmp_path / "py.pvox")
    assert (tmp_path / "py.pvox").read_bytes() == (out / "map.pvox").read_bytes()
    assert mapper.map.voxels_csv() == (out / "voxels.csv").read_text()


def test_mapper_aligns_without_measurements():
    # A corner of three planes, scanned twice from poses 5 cm apart with the command saying 0:
    # the alignment finds the move.
    g = np.arange(0, 40) * 0.025
    a, b = np.meshgrid(g, g, indexing="ij")
    a, b = a.ravel(), b.ravel()
    corner = np.concatenate([np.stack([a, b, np.zeros_like(a)], 1), np.stack([a, np.zeros_like(a), b], 1),
                             np.stack([np.zeros_like(a), a, b], 1)]) + [-0.5, -0.5, -0.5]
    mapper = hmap.pvox.Mapper(fixed_edge=0.05)
    first = mapper.add_scan(corner, np.eye(4))
    assert first["edge"] == pytest.approx(0.05)
    moved = corner - [0.05, 0.0, 0.0]                    # the sensor moved +5 cm along x
    r = mapper.add_scan(moved, np.eye(4))
    assert r["measured_by_alignment"] and r["align"]["valid"]
    assert r["measurement"][0] == pytest.approx(0.05, abs=0.01)


def test_bad_input():
    with pytest.raises(hmap.Error):                      # the library's: the edge must be positive
        hmap.pvox.VoxelMap(0.0)
    m = hmap.pvox.VoxelMap(0.1)
    with pytest.raises(ValueError, match=r"points must have shape \(N, 3\), got \(4, 2\)"):
        m.insert(np.zeros((4, 2)), np.eye(4))
    with pytest.raises(ValueError, match="float32 or float64, got dtype int64"):
        m.insert(np.zeros((4, 3), dtype=np.int64), np.eye(4))
    with pytest.raises(ValueError, match="row 1 is not finite"):
        m.insert(np.array([[1.0, 0, 0], [math.nan, 0, 0]]), np.eye(4))
    assert m.insert(np.array([[1.0, 0, 0], [math.nan, 0, 0]]), np.eye(4), non_finite="drop")["hits"] == 1
    with pytest.raises(ValueError, match="T_map_sensor must be a 4x4"):
        m.insert(np.zeros((1, 3)), np.eye(3))
    with pytest.raises(ValueError, match="free_space must be"):
        m.insert(np.zeros((1, 3)), np.eye(4), free_space="yes")
    with pytest.raises(ValueError, match="xyz: row 0 is not finite"):
        m.probability(np.array([[math.inf, 0, 0]]))
    with pytest.raises(ValueError, match="filter must be"):
        hmap.pvox.Mapper(filter="ekf")
    with pytest.raises(ValueError, match="measured_xy must be two finite numbers"):
        hmap.pvox.Mapper().add_scan(np.zeros((1, 3)), np.eye(4), [1.0, math.nan])


def test_load_errors_carry_the_library_message(tmp_path):
    bad = tmp_path / "bad.pvox"
    bad.write_bytes(b"not a pvox file at all, but long enough to have a header" * 4)
    with pytest.raises(hmap.InputError, match="bad.pvox"):
        hmap.pvox.VoxelMap.load(bad)
    with pytest.raises(hmap.InputError):
        hmap.pvox.VoxelMap.load(tmp_path / "missing.pvox")
