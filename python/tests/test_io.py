"""hmap.io: the library's readers, numpy out; the CLI's map equals the Python one on the same scans."""

import os
import pathlib
import subprocess

import numpy as np
import pytest

import hmap
from conftest import require_data


def test_read_cloud_xyz(tmp_path):
    path = tmp_path / "three.xyz"
    path.write_text("1 2 3\n4.5 -5 6\n\n7 8 9.25\n")
    pts = hmap.io.read_cloud(path)
    assert pts.dtype == np.float32
    np.testing.assert_array_equal(pts, [[1, 2, 3], [4.5, -5, 6], [7, 8, 9.25]])


def test_read_cloud_kitti_bin_matches_numpy(tmp_path):
    raw = np.array([[1, 2, 3, 0.5], [np.nan, 0, 0, 1], [-4, 5.5, 6, 0]], dtype=np.float32)
    path = tmp_path / "scan.bin"
    raw.tofile(path)
    # x y z intensity records; the intensity is dropped, and so is the non-finite point.
    np.testing.assert_array_equal(hmap.io.read_cloud(path), raw[[0, 2], :3])


def test_read_errors_carry_the_librarys_message(tmp_path):
    with pytest.raises(hmap.InputError, match=r"scan\.bin.*multiple of 16"):
        (tmp_path / "scan.bin").write_bytes(b"12345")
        hmap.io.read_cloud(tmp_path / "scan.bin")
    with pytest.raises(hmap.InputError, match=r"cloud\.abc"):
        (tmp_path / "cloud.abc").write_text("1 2 3\n")
        hmap.io.read_cloud(tmp_path / "cloud.abc")
    with pytest.raises(hmap.InputError, match="missing.pcd"):
        hmap.io.read_cloud(tmp_path / "missing.pcd")
    with pytest.raises(hmap.InputError, match="missing.hmap"):
        hmap.Map.load(tmp_path / "missing.hmap")
    assert issubclass(hmap.InputError, hmap.Error) and issubclass(hmap.Error, ValueError)


def test_read_poses(tmp_path):
    path = tmp_path / "poses.txt"
    path.write_text("1 0 0 1.5 0 1 0 2 0 0 1 3\n0 -1 0 0 1 0 0 0 0 0 1 0\n")
    poses = hmap.io.read_poses(path)
    assert poses.shape == (2, 4, 4)
    np.testing.assert_array_equal(poses[0][:3, 3], [1.5, 2, 3])
    np.testing.assert_array_equal(poses[1][:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    np.testing.assert_array_equal(poses[:, 3], [[0, 0, 0, 1]] * 2)


def test_real_kitti_scan_matches_numpy():
    scan = sorted((require_data("kitti_hdl64_seq16") / "velodyne").glob("*.bin"))[0]
    raw = np.fromfile(scan, dtype=np.float32).reshape(-1, 4)[:, :3]
    raw = raw[np.isfinite(raw).all(axis=1)]
    np.testing.assert_array_equal(hmap.io.read_cloud(scan), raw)


def test_python_map_equals_the_cli_map_byte_for_byte(tmp_path):
    """The same scans, poses and parameters: `hmap map` and HybridMapper save the same bytes."""
    data = require_data("balm_os0")
    cli = pathlib.Path(os.environ.get("HMAP_BIN", ""))
    if not cli.is_file():
        pytest.skip("the hmap tool is not built (HMAP_BIN)")
    scans = 4
    subprocess.run([str(cli), "map", "--kitti", str(data), "--scans", str(scans), "--preset", "outdoor",
                    "--cell", "0.2", "--out", str(tmp_path / "cli.hmap")], check=True, capture_output=True)
    # The CLI adapts some parameters to the first scan (the ring gap): take them from its map.
    params = hmap.Map.load(tmp_path / "cli.hmap").params
    mapper = hmap.HybridMapper(params)
    poses = hmap.io.read_poses(data / "poses.txt")
    for k, scan in enumerate(sorted((data / "velodyne").glob("*.bin"))[:scans]):
        mapper.integrate(hmap.io.read_cloud(scan), poses[k])
    mapper.map.save(tmp_path / "py.hmap")
    assert (tmp_path / "py.hmap").read_bytes() == (tmp_path / "cli.hmap").read_bytes()


def write_kitti_folder(root, scans, poses=None, times=None):
    (root / "velodyne").mkdir(parents=True)
    for k, pts in enumerate(scans):
        np.hstack([pts, np.zeros((len(pts), 1))]).astype(np.float32).tofile(root / "velodyne" / f"{k:06d}.bin")
    if poses is not None:
        np.savetxt(root / "poses.txt", poses[:, :3, :].reshape(len(poses), 12))
    if times is not None:
        np.savetxt(root / "times.txt", times)


def test_kitti_sequence_yields_points_poses_and_stamps(tmp_path):
    scans = [np.array([[1, 2, 3]], dtype=np.float32) * (k + 1) for k in range(3)]
    poses = np.tile(np.eye(4), (3, 1, 1))
    poses[:, 0, 3] = [0.0, 1.0, 2.5]
    write_kitti_folder(tmp_path, scans, poses, [0.0, 0.1, 0.2])
    got = list(hmap.io.kitti_sequence(tmp_path))
    assert len(got) == 3
    for k, (points, pose, stamp) in enumerate(got):
        np.testing.assert_array_equal(points, scans[k])
        np.testing.assert_array_equal(pose, poses[k])  # no calib.txt: the poses as they are
        assert stamp == pytest.approx(0.1 * k)
    assert len(list(hmap.io.kitti_sequence(tmp_path, max_scans=2))) == 2


def test_kitti_sequence_without_poses_and_its_errors(tmp_path):
    write_kitti_folder(tmp_path / "a", [np.zeros((2, 3))])
    [(points, pose, stamp)] = hmap.io.kitti_sequence(tmp_path / "a")
    assert points.shape == (2, 3) and pose is None and stamp is None
    write_kitti_folder(tmp_path / "b", [np.zeros((2, 3))] * 2, times=[0.0])
    with pytest.raises(hmap.InputError, match="times.txt"):
        next(hmap.io.kitti_sequence(tmp_path / "b"))
    with pytest.raises(hmap.InputError, match="velodyne"):
        next(hmap.io.kitti_sequence(tmp_path / "missing"))


def test_kitti_sequence_reads_the_real_scans():
    data = require_data("kitti_hdl64_seq16")
    paths = sorted((data / "velodyne").glob("*.bin"))[:2]
    for (points, _, _), path in zip(hmap.io.kitti_sequence(data, max_scans=2), paths):
        np.testing.assert_array_equal(points, hmap.io.read_cloud(path))
