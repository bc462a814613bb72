"""hmap.io: the library's readers, numpy out; the CLI's map equals the Python one on the same scans."""

import os
import pathlib
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest

import hmap
from conftest import cli_or_skip, data_dir, require_data


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


# ---------------------------------------------------------------------------------------------
# Scan sequences of every kind, through the library's one opener (the CLI's --kitti, files,
# --rgbd / --tum, --bag): the same points and poses as `hmap map` reads.


def map_like_the_cli(tmp_path, cli, cli_args, sequence):
    """`hmap map ARGS --out cli.hmap`, then the same scans from `sequence` into a HybridMapper with
    the CLI map's parameters: both maps' bytes."""
    subprocess.run([str(cli), "map", *map(str, cli_args), "--out", str(tmp_path / "cli.hmap")], check=True,
                   capture_output=True)
    mapper = hmap.HybridMapper(hmap.Map.load(tmp_path / "cli.hmap").params)
    for points, pose, *_ in sequence:
        mapper.integrate(points, pose)
    mapper.map.save(tmp_path / "py.hmap")
    return (tmp_path / "py.hmap").read_bytes(), (tmp_path / "cli.hmap").read_bytes()


def test_scan_sequence_of_files_with_a_tum_pose_file(tmp_path):
    files = []
    for k in range(3):
        files.append(tmp_path / f"s{k}.xyz")
        files[-1].write_text(f"{k} 0 1\n2 {k}.5 -1\n")
    (tmp_path / "poses.txt").write_text("10.5 1 2 3 0 0 0 1\n10.75 0 0 0 0 0 1 0\n11 0 0 1 0 0 0 1\n")
    seq = hmap.io.scan_sequence(files, tmp_path / "poses.txt")
    assert len(seq) == 3 and iter(seq) is seq and seq.names == [str(f) for f in files]
    got = list(seq)
    assert len(got) == 3 and len(seq) == 3  # len(): the scans of the source, read or not
    with pytest.raises(StopIteration):
        next(seq)
    for k, (points, pose, stamp) in enumerate(got):
        np.testing.assert_array_equal(points, [[k, 0, 1], [2, k + 0.5, -1]])
        assert stamp == [10.5, 10.75, 11.0][k]
    np.testing.assert_array_equal(got[0][1][:3, 3], [1, 2, 3])
    np.testing.assert_allclose(got[1][1][:3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-15)  # qz = 1: 180 deg about z
    # up="x": T_map_world turns the world's x to the map's z, for every pose.
    turned = [pose for _, pose, _ in hmap.io.scan_sequence(files, tmp_path / "poses.txt", up="x")]
    np.testing.assert_allclose(turned[0][:3, 3], [-3, 2, 1], atol=1e-12)
    [(_, alone, stamp)] = hmap.io.scan_sequence(files[0])  # one file, no poses
    assert alone is None and stamp is None
    with pytest.raises(hmap.InputError, match=r"poses\.txt: holds 3 poses for 2 scans"):
        hmap.io.scan_sequence(files[:2], tmp_path / "poses.txt")
    with pytest.raises(hmap.Error, match="--up and --rotation turn the poses of the scans; these scans have none"):
        hmap.io.scan_sequence(files, up="x")
    with pytest.raises(ValueError, match="rotation must be a 3x3"):
        hmap.io.scan_sequence(files, tmp_path / "poses.txt", rotation=np.eye(2))


def test_pcd_per_point_times_come_with_with_times(tmp_path):
    pcd = tmp_path / "sweep.pcd"
    pcd.write_text("VERSION 0.7\nFIELDS x y z t\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\n"
                   "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 2 3 0\n4 5 6 0.05\n7 8 9 0.1\n")
    [(points, pose, stamp, times)] = hmap.io.scan_sequence([pcd], with_times=True)
    np.testing.assert_array_equal(points, [[1, 2, 3], [4, 5, 6], [7, 8, 9]])
    assert times.dtype == np.float32 and pose is None and stamp is None
    np.testing.assert_allclose(times, [0, 0.05, 0.1], rtol=1e-6)
    (tmp_path / "plain.xyz").write_text("1 2 3\n")
    [(_, _, _, none)] = hmap.io.scan_sequence([tmp_path / "plain.xyz"], with_times=True)
    assert none is None


def test_kitti_sequence_map_equals_the_cli_map(tmp_path):
    data = require_data("balm_os0")
    seq = hmap.io.kitti_sequence(data, max_scans=3)
    assert len(seq) == 3 and seq.poses.shape == (3, 4, 4) and seq.stamps.shape == (3,)
    py, cli = map_like_the_cli(tmp_path, cli_or_skip(), ["--kitti", data, "--scans", 3, "--cell", 0.2], seq)
    assert py == cli


def test_rgbd_sequence_7scenes_map_equals_the_cli_map(tmp_path):
    data = require_data("rgbd_7scenes")
    seq = hmap.io.rgbd_sequence(data, max_frames=3)
    assert len(seq) == 3 and "RGB-D frames" in seq.description and "floor plane" in seq.description
    py, cli = map_like_the_cli(tmp_path, cli_or_skip(), ["--rgbd", data, "--scans", 3, "--preset", "indoor"], seq)
    assert py == cli


def write_png16(path, depth):
    """A 16-bit greyscale PNG of `depth` (H, W) uint16, written here with zlib alone."""
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
    h, w = depth.shape
    rows = b"".join(b"\x00" + depth[r].astype(">u2").tobytes() for r in range(h))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)) +
                     chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def write_tum_folder(root):
    """Two 8x6 depth frames (TUM: 5000 units per metre, 0 = no depth), 1 m and 2 m away, the second
    camera 0.5 m along x; intrinsics fx = fy = 4, cx = 3.5, cy = 2.5."""
    (root / "depth").mkdir(parents=True)
    depth = np.full((6, 8), 5000, dtype=np.uint16)
    depth[0, 0] = 0
    write_png16(root / "depth" / "1.0.png", depth)
    write_png16(root / "depth" / "2.0.png", depth * 2)
    (root / "depth.txt").write_text("# timestamp filename\n1.0 depth/1.0.png\n2.0 depth/2.0.png\n")
    (root / "groundtruth.txt").write_text("1.0 0 0 0 0 0 0 1\n2.0 0.5 0 0 0 0 0 1\n")
    (root / "intrinsics.txt").write_text("4 4 3.5 2.5\n")


def test_rgbd_sequence_of_a_tum_folder(tmp_path):
    root = tmp_path / "tum"
    write_tum_folder(root)
    seq = hmap.io.rgbd_sequence(root, tum=True, intrinsics=root / "intrinsics.txt", up="-y")
    assert len(seq) == 2 and "(TUM)" in seq.description and "world up axis -y" in seq.description
    frames = list(seq)
    # By hand: pixel (u, v) at depth d is ((u - 3.5) d / 4, (v - 2.5) d / 4, d), the pixel (0, 0) has none.
    v, u = np.mgrid[0:6, 0:8]
    keep = (u + v) > 0
    for (points, pose, stamp), d, x in zip(frames, (1.0, 2.0), (0.0, 0.5)):
        expected = np.stack([(u[keep] - 3.5) * d / 4, (v[keep] - 2.5) * d / 4, np.full(keep.sum(), d)], axis=1)
        np.testing.assert_allclose(points[np.lexsort(points.T[::-1])], expected[np.lexsort(expected.T[::-1])], atol=1e-6)
        # up -y: T_map_world takes the world's -y (the optical frame's up) to z; x stays x.
        np.testing.assert_allclose(pose[:3, :3], [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-12)
        np.testing.assert_allclose(pose[:3, 3], [x, 0, 0], atol=1e-12)
        assert stamp is None  # RGB-D frames carry no scan stamps (as for the CLI)
    cli = cli_or_skip()
    py, cli_map = map_like_the_cli(tmp_path, cli, ["--tum", root, "--intrinsics", root / "intrinsics.txt", "--up", "-y",
                                                   "--preset", "indoor", "--cell", 0.05],
                                   hmap.io.rgbd_sequence(root, tum=True, intrinsics=root / "intrinsics.txt", up="-y"))
    assert py == cli_map
    # A 7-Scenes layout is not TUM: tum=True refuses it, tum="auto" tells the layout itself.
    (root / "depth.txt").unlink()
    with pytest.raises(hmap.InputError):
        hmap.io.rgbd_sequence(root, tum=True)
    with pytest.raises(ValueError, match="tum must be"):
        hmap.io.rgbd_sequence(root, tum="yes")


def test_sequence_errors_are_the_librarys_one_line(tmp_path):
    with pytest.raises(hmap.InputError, match=r"^.*missing: is not a folder$"):
        hmap.io.rgbd_sequence(tmp_path / "missing")
    with pytest.raises(hmap.InputError, match="velodyne"):
        hmap.io.kitti_sequence(tmp_path / "missing")
    with pytest.raises(hmap.InputError, match="missing.xyz"):
        next(hmap.io.scan_sequence([tmp_path / "missing.xyz"]))
    with pytest.raises(hmap.Error, match="give one input: --kitti DIR, scan files, --rgbd DIR, --tum DIR or --bag FILE"):
        hmap.io.open_source(kitti=str(tmp_path), rgbd=str(tmp_path))
    with pytest.raises(hmap.InputError, match="missing.bag"):
        hmap.io.bag_sequence(tmp_path / "missing.bag")


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """The small bags of tests/ros (the first 3 balm_os0 scans, every 20th point), by ROS's own
    writer (Debian python3-rosbag)."""
    require_data("balm_os0")
    out = tmp_path_factory.mktemp("bags")
    script = pathlib.Path(__file__).resolve().parents[2] / "tests" / "ros" / "make_test_bags.py"
    run = subprocess.run([sys.executable, str(script), str(data_dir()), str(out), "3", "20"], capture_output=True, text=True)
    if run.returncode != 0 and "No module named" in run.stderr:
        pytest.skip("python3-rosbag is not installed: " + run.stderr.strip().splitlines()[-1])
    assert run.returncode == 0, run.stderr
    return out


def test_bag_sequence_map_equals_the_cli_map(tmp_path, bags):
    seq = hmap.io.bag_sequence(bags / "tf.bag", tf_frames=["map"])
    assert len(seq) == 3 and seq.names[0].startswith("/os_cloud@") and seq.stamps.shape == (3,)
    times = np.loadtxt(require_data("balm_os0") / "times.txt")[:3]
    np.testing.assert_allclose(seq.stamps, times, atol=1e-6)
    # tf.bag: map -> odom is (1, 2, 0) and odom -> os_sensor interpolates to poses.txt's P_k (its
    # translation exactly; its rotation as the script's quaternions give it, to about 1e-3).
    truth = hmap.io.read_poses(require_data("balm_os0") / "poses.txt")[:3]
    np.testing.assert_allclose(seq.poses[:, :3, 3], truth[:, :3, 3] + [1, 2, 0], atol=1e-6)
    np.testing.assert_allclose(seq.poses[:, :3, :3], truth[:, :3, :3], atol=2e-3)
    py, cli = map_like_the_cli(tmp_path, cli_or_skip(), ["--bag", bags / "tf.bag", "--tf-frames", "map", "--preset",
                                                         "outdoor"], seq)
    assert py == cli


def test_bag_sequence_times_topics_and_errors(bags):
    [(points, pose, stamp, times)] = hmap.io.bag_sequence(bags / "imu.bag", pose_topic="/odom", max_scans=1,
                                                          with_times=True)
    assert times.shape == (len(points),) and times.dtype == np.float32
    assert times.min() == 0 and times.max() == pytest.approx(0.099, abs=1e-6)  # uint32 ns, 0..99 ms over the points
    assert pose.shape == (4, 4) and stamp > 1e9
    with pytest.raises(hmap.InputError, match=r"^.*imu\.bag: topic /nope has no messages \(see hmap bag-info\)$"):
        hmap.io.bag_sequence(bags / "imu.bag", cloud_topic="/nope", pose_topic="/odom")
    with pytest.raises(hmap.Error, match="give either --pose-topic or --tf-frames, not both"):
        hmap.io.bag_sequence(bags / "tf.bag", pose_topic="/odom", tf_frames="map")


def test_slam_on_a_bag_with_its_imu_gives_the_poses_of_hmap_slam(tmp_path, bags):
    """`hmap slam --bag imu.bag --pose-topic /odom` takes the bag's /imu and its poses' attitude; the
    same from bag_sequence, read_bag_imu and Slam gives the same poses and map."""
    cli = cli_or_skip()
    bag = bags / "imu.bag"
    run = subprocess.run([str(cli), "slam", "--bag", str(bag), "--pose-topic", "/odom", "--out", str(tmp_path / "O")],
                         check=True, capture_output=True, text=True)
    imu = hmap.io.read_bag_imu(bag)
    assert f"IMU: {len(imu['stamps'])} samples from {bag} /imu" in run.stdout
    np.testing.assert_array_equal(imu["accel"][0], [0, 0, 9.81])  # as make_test_bags.py writes them
    assert imu["orientation"] is None and hmap.io.read_bag_imu(bags / "tf.bag") is None
    seq = hmap.io.bag_sequence(bag, pose_topic="/odom", with_times=True)
    slam = None
    for points, pose, stamp, times in seq:
        if slam is None:
            slam = hmap.slam.Slam(hmap.params_for_scan(points)["params"], imu=imu)
        step = slam.process(points, stamp, times, attitude=pose)  # the bag's poses give the attitude
        assert step["deskewed"]
    np.testing.assert_allclose(slam.poses[:, :3, :], np.loadtxt(tmp_path / "O" / "poses.txt").reshape(-1, 3, 4),
                               rtol=0, atol=1e-9)
    slam.map.save(tmp_path / "py.hmap")
    assert (tmp_path / "py.hmap").read_bytes() == (tmp_path / "O" / "map.hmap").read_bytes()
    with pytest.raises(hmap.InputError, match="imu_two.bag"):
        hmap.io.read_bag_imu(bags / "imu_two.bag")  # two Imu topics, none named
