"""hmap.sim: scans equal to `hmap simulate`'s, hand-computed geometry, fixed seeds, bad input."""

import json
import math
import subprocess
import threading
import time

import numpy as np
import pytest

import hmap
from conftest import cli_or_skip



def read_kitti_poses(path):
    rows = np.loadtxt(path, ndmin=2).reshape(-1, 3, 4)
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    poses[:, :3, :] = rows
    return poses


def read_pcd_xyzt(path):
    """A binary PCD of float fields x y z t, as write_pcd_with_time writes it."""
    data = path.read_bytes()
    header, _, body = data.partition(b"DATA binary\n")
    assert b"FIELDS x y z t" in header
    return np.frombuffer(body, dtype="<f4").reshape(-1, 4)


def simulate_cli(tmp_path, *args):
    out = tmp_path / "seq"
    subprocess.run([str(cli_or_skip()), "simulate", "--frames", "2", "--truth-spacing", "2", "--out", str(out), *args],
                   check=True, capture_output=True, text=True)
    return out


def test_parking_vlp16_equals_the_cli(tmp_path):
    out = simulate_cli(tmp_path, "--scene", "parking", "--sensor", "vlp16", "--seed", "3")
    scene = hmap.sim.Scene("parking")
    path = hmap.sim.car_path(hmap.sim.route("parking"))  # the CLI's: a spinning lidar at 1.73 m
    lidar = hmap.sim.Sensor("vlp16", seed=3)
    truth = read_kitti_poses(out / "poses.txt")
    np.testing.assert_allclose(truth, path.poses[:2], atol=1e-12)
    np.testing.assert_allclose(np.loadtxt(out / "times.txt"), path.times[:2], atol=1e-12)
    for k in range(2):  # the same sensor for both frames: its noise generator runs on as the CLI's
        scan = lidar.scan(scene, path.poses[k], path.times[k])
        cli = np.fromfile(out / "velodyne" / f"{k:06d}.bin", dtype="<f4").reshape(-1, 4)[:, :3]
        assert scan["points"].dtype == np.float32 and scan["points"].shape[1] == 3
        assert len(scan["points"]) > 20000
        np.testing.assert_array_equal(scan["points"], cli)
        assert scan["time"] is None
        assert len(scan["channel"]) == len(scan["primitive"]) == len(scan["kind"]) == len(cli)
    odometry = hmap.sim.noisy_odometry(path.poses[:2], seed=3)
    np.testing.assert_allclose(read_kitti_poses(out / "odometry.txt"), odometry, atol=1e-12)


def test_parking_os0_equals_the_cli(tmp_path):
    # The OS0-64 preset: 64 rings over +-45 deg, 1024 columns, on the car like the other spinning lidars.
    out = simulate_cli(tmp_path, "--scene", "parking", "--sensor", "os0-64", "--seed", "5")
    path = hmap.sim.car_path(hmap.sim.route("parking"))
    lidar = hmap.sim.Sensor("os0-64", seed=5)
    assert "os0-64" in hmap.sim.Sensor.names()
    scan = lidar.scan(hmap.sim.Scene("parking"), path.poses[0], path.times[0])
    cli = np.fromfile(out / "velodyne" / "000000.bin", dtype="<f4").reshape(-1, 4)[:, :3]
    np.testing.assert_array_equal(scan["points"], cli)
    assert scan["rays"] == 64 * 1024
    assert set(np.unique(scan["channel"])) <= set(range(64))
    elevation = np.degrees(np.arctan2(cli[:, 2], np.hypot(cli[:, 0], cli[:, 1])))
    assert elevation.min() > -45.5 and elevation.max() < 45.5


def test_office_kinect_equals_the_cli(tmp_path):
    out = simulate_cli(tmp_path, "--scene", "office", "--sensor", "kinect", "--seed", "2")
    path = hmap.sim.diff_drive_path(hmap.sim.route("office"), sensor_height=0.8)  # the CLI's Kinect height
    camera = hmap.sim.Sensor("kinect", seed=2)
    scene = hmap.sim.Scene("office")
    for k in range(2):
        scan = camera.scan(scene, path.poses[k], path.times[k])
        cli = np.fromfile(out / "velodyne" / f"{k:06d}.bin", dtype="<f4").reshape(-1, 4)[:, :3]
        assert len(cli) > 1000
        np.testing.assert_array_equal(scan["points"], cli)


def test_sweep_equals_the_cli_with_point_times(tmp_path):
    out = simulate_cli(tmp_path, "--scene", "parking", "--sensor", "vlp16", "--sweep", "--seed", "5")
    path = hmap.sim.car_path(hmap.sim.route("parking"))
    lidar = hmap.sim.Sensor("vlp16", seed=5)
    scene = hmap.sim.Scene("parking")
    for k in range(2):
        sweep = lidar.sweep(scene, path, path.times[k])
        cli = read_pcd_xyzt(out / "velodyne" / f"{k:06d}.pcd")
        np.testing.assert_array_equal(sweep["points"], cli[:, :3])
        np.testing.assert_array_equal(sweep["time"], cli[:, 3])
        assert sweep["time"].dtype == np.float32
        assert 0.0 <= sweep["time"].min() and sweep["time"].max() < 0.1  # one 10 Hz revolution


def test_simulate_equals_the_cli_files(tmp_path):
    from test_writers import read_ply

    out = simulate_cli(tmp_path, "--scene", "parking", "--sensor", "vlp16", "--seed", "4", "--imu-rate", "100")
    rec = hmap.sim.simulate("parking", "vlp16", frames=2, truth_spacing=2, seed=4, imu_rate=100)
    assert len(rec["scans"]) == 2 and rec["point_times"] is None
    for k, scan in enumerate(rec["scans"]):
        cli = np.fromfile(out / "velodyne" / f"{k:06d}.bin", dtype="<f4").reshape(-1, 4)[:, :3]
        np.testing.assert_array_equal(scan, cli)
    assert rec["points"] == sum(len(s) for s in rec["scans"])
    np.testing.assert_allclose(read_kitti_poses(out / "poses.txt"), rec["poses"], atol=1e-12)
    np.testing.assert_allclose(read_kitti_poses(out / "odometry.txt"), rec["odometry"], atol=1e-12)
    np.testing.assert_allclose(np.loadtxt(out / "times.txt"), rec["times"], atol=1e-12)
    for name in ("truth_surface", "truth_ground", "truth_seen"):
        ply = {"truth_surface": "truth.ply"}.get(name, name + ".ply")
        vertices, _ = read_ply(out / ply)
        assert len(vertices) > 100
        np.testing.assert_array_equal(rec[name], vertices["xyz"], err_msg=name)
    imu = np.loadtxt(out / "imu.txt", ndmin=2)
    assert len(imu) == len(rec["imu"]["t"]) > 5
    np.testing.assert_allclose(imu[:, 0], rec["imu"]["t"], rtol=1e-15)
    np.testing.assert_allclose(imu[:, 1:4], rec["imu"]["gyro"], rtol=1e-15)
    np.testing.assert_allclose(imu[:, 4:7], rec["imu"]["accel"], rtol=1e-15)
    # The parts give the same as the whole: the first frame is Sensor.scan at the path's first pose.
    path = hmap.sim.car_path(hmap.sim.route("parking"))
    np.testing.assert_array_equal(hmap.sim.Sensor("vlp16", 4).scan(hmap.sim.Scene("parking"), path.poses[0])["points"],
                                  rec["scans"][0])


def test_simulate_sweep_and_own_scene(tmp_path):
    out = simulate_cli(tmp_path, "--scene", "parking", "--sensor", "hdl64", "--sweep", "--stride", "7")
    rec = hmap.sim.simulate("parking", "hdl64", frames=2, stride=7, truth_spacing=2, sweep=True)
    for k in range(2):
        cli = read_pcd_xyzt(out / "velodyne" / f"{k:06d}.pcd")
        np.testing.assert_array_equal(rec["scans"][k], cli[:, :3])
        np.testing.assert_array_equal(rec["point_times"][k], cli[:, 3])
    # A scene of one's own drives the office route, as --scene-file does.
    scene_file = tmp_path / "flat.json"
    scene_file.write_text(FLAT)
    own = tmp_path / "own"
    subprocess.run([str(cli_or_skip()), "simulate", "--scene-file", str(scene_file), "--sensor", "kinect", "--frames", "2",
                    "--truth-spacing", "2", "--out", str(own)], check=True, capture_output=True)
    rec = hmap.sim.simulate(hmap.sim.Scene.from_json(FLAT), "kinect", frames=2, truth_spacing=2)
    np.testing.assert_allclose(read_kitti_poses(own / "poses.txt"), rec["poses"], atol=1e-12)
    office = hmap.sim.diff_drive_path(hmap.sim.route("office"), sensor_height=0.8)
    np.testing.assert_allclose(rec["poses"], office.poses[:2], atol=1e-12)
    for k in range(2):
        cli = np.fromfile(own / "velodyne" / f"{k:06d}.bin", dtype="<f4").reshape(-1, 4)[:, :3]
        assert len(cli) > 1000
        np.testing.assert_array_equal(rec["scans"][k], cli)
    # A bad scene file: the CLI names the file, the library the JSON path, as before the driver moved.
    bad = tmp_path / "bad.json"
    bad.write_text('{"objects": [{"type": "box", "size": [1, 2]}]}')
    r = subprocess.run([str(cli_or_skip()), "simulate", "--scene-file", str(bad), "--out", str(tmp_path / "b")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and f"{bad}: objects[0]" in r.stderr, r.stderr
    with pytest.raises(hmap.Error, match="--sweep needs a spinning lidar"):
        hmap.sim.simulate("office", "kinect", frames=1, sweep=True)
    with pytest.raises(hmap.Error, match="--stride must be at least 1"):
        hmap.sim.simulate("office", frames=1, stride=0)
    with pytest.raises(ValueError, match="scene must be a built-in scene's name or an hmap.sim.Scene"):
        hmap.sim.simulate(3)


FLAT = json.dumps({"objects": [{"type": "ground", "center": [0, 0, 0], "size": [200, 200], "kind": "ground"}]})


def test_noise_free_vlp16_over_a_plane_hand_computed():
    # A VLP-16 2 m above a plane: ring r looks (-15 + 2 r) deg down; rings 0..6 (-15..-3 deg) hit it
    # at 2 / tan(elevation) horizontally, z = -2 in the sensor frame; -1 deg would reach 114.6 m,
    # beyond the 100 m range; the upper rings see nothing. 360 / 0.2 = 1800 columns.
    scene = hmap.sim.Scene.from_json(FLAT)
    T = np.eye(4)
    T[2, 3] = 2.0
    scan = hmap.sim.Sensor("vlp16", noise=False).scan(scene, T)
    pts = scan["points"]
    assert len(pts) == 7 * 1800
    np.testing.assert_allclose(pts[:, 2], -2.0, atol=1e-4)
    rings = scan["channel"]
    assert set(rings.tolist()) == set(range(7))
    kinds = hmap.sim.kind_names()
    assert kinds[0] == "ground" and "wall" in kinds
    assert set(scan["kind"].tolist()) == {kinds.index("ground")}  # the plane's "kind": "ground"
    horizontal = np.hypot(pts[:, 0], pts[:, 1])
    expected = 2.0 / np.tan(np.radians(15.0 - 2.0 * rings))
    np.testing.assert_allclose(horizontal, expected, rtol=1e-4)


def test_points_come_out_without_a_copy():
    # The library's point vector becomes the array's buffer (owned by a capsule), C-contiguous.
    scan = hmap.sim.Sensor("vlp16").scan(hmap.sim.Scene("office"), hmap.sim.diff_drive_path(hmap.sim.route("office")).poses[0])
    pts = scan["points"]
    assert not pts.flags.owndata and type(pts.base).__name__ == "PyCapsule"
    assert pts.flags.c_contiguous and pts.strides == (12, 4) and len(pts) > 1000
    rec = hmap.sim.simulate("office", frames=1, truth_spacing=1.0)
    assert all(not a.flags.owndata for a in rec["scans"] + [rec["truth_seen"], rec["truth_surface"]])
    far = np.eye(4)
    far[2, 3] = 100.0                                       # 100 m above the plane, the Kinect reaches 4.5 m
    empty = hmap.sim.Sensor("kinect").scan(hmap.sim.Scene.from_json(FLAT), far)["points"]
    assert empty.shape == (0, 3) and empty.dtype == np.float32


def test_fixed_seeds_give_identical_arrays():
    scene = hmap.sim.Scene("boxes")
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.35, 0.0]
    a = hmap.sim.Sensor("utm30lx-tilt", seed=4).scan(scene, T)["points"]
    b = hmap.sim.Sensor("utm30lx-tilt", seed=4).scan(scene, T)["points"]
    c = hmap.sim.Sensor("utm30lx-tilt", seed=5).scan(scene, T)["points"]
    assert len(a) > 1000
    np.testing.assert_array_equal(a, b)
    assert not (a.shape == c.shape and np.array_equal(a, c))
    s1 = scene.sample_surface(0.2, seed=9)
    np.testing.assert_array_equal(s1, scene.sample_surface(0.2, seed=9))
    lo, hi = np.array(scene.bounds[0]), np.array(scene.bounds[1])
    assert np.all(s1 >= lo - 1e-4) and np.all(s1 <= hi + 1e-4)


def test_write_sequence_reads_back(tmp_path):
    scene = hmap.sim.Scene("office")
    path = hmap.sim.diff_drive_path(hmap.sim.route("office"))
    lidar = hmap.sim.Sensor("vlp16", seed=1)
    frames = [lidar.scan(scene, path.poses[k], path.times[k])["points"] for k in range(3)]
    odometry = hmap.sim.noisy_odometry(path.poses[:3])
    hmap.sim.write_sequence(tmp_path / "seq", frames, path.poses[:3], path.times[:3], odometry=odometry)
    back = list(hmap.io.kitti_sequence(tmp_path / "seq"))
    assert len(back) == 3
    for (points, pose, stamp), frame, truth, t in zip(back, frames, path.poses, path.times):
        np.testing.assert_array_equal(points, frame)
        np.testing.assert_allclose(pose, truth, atol=1e-12)
        assert stamp == pytest.approx(t, abs=1e-9)
    np.testing.assert_allclose(read_kitti_poses(tmp_path / "seq" / "odometry.txt"), odometry, atol=1e-12)
    with pytest.raises(ValueError, match="times: element 1 is not finite"):
        hmap.sim.write_sequence(tmp_path / "nan", frames[:2], path.poses[:2], [0.0, math.nan])
    with pytest.raises(hmap.Error):  # the library's: counts differ
        hmap.sim.write_sequence(tmp_path / "bad", frames, path.poses[:2], path.times[:2])


def test_trajectory_pose_at_interpolates():
    poses = np.tile(np.eye(4), (3, 1, 1))
    poses[:, 0, 3] = [0.0, 1.0, 2.0]
    path = hmap.sim.Trajectory(poses, [0.0, 1.0, 2.0])
    assert len(path) == 3
    np.testing.assert_allclose(path.pose_at(0.5)[:3, 3], [0.5, 0.0, 0.0], atol=1e-12)  # straight, uniform
    np.testing.assert_allclose(path.pose_at(5.0), poses[2], atol=1e-12)                 # clamped


def test_bad_input():
    scene = hmap.sim.Scene("boxes")
    with pytest.raises(hmap.Error, match="boxes"):   # the library lists the known scenes
        hmap.sim.Scene("garage")
    with pytest.raises(hmap.Error, match="unknown sensor 'os1' \\(known: vlp16"):
        hmap.sim.Sensor("os1")
    lidar = hmap.sim.Sensor("vlp16")
    with pytest.raises(ValueError, match="T_world_sensor must be a 4x4"):
        lidar.scan(scene, np.eye(3))
    with pytest.raises(ValueError, match="T_world_sensor: .*rigid"):
        lidar.scan(scene, np.diag([2.0, 1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="t must be finite"):
        lidar.scan(scene, np.eye(4), math.nan)
    with pytest.raises(ValueError, match="sweep needs a spinning lidar"):
        hmap.sim.Sensor("kinect").sweep(scene, hmap.sim.car_path(hmap.sim.route("parking")), 0.0)
    with pytest.raises(ValueError, match=r"waypoints must be an \(N, 3\)"):
        hmap.sim.car_path(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="row 1 is not finite"):
        hmap.sim.diff_drive_path([[0, 0], [math.nan, 1]])
    with pytest.raises(hmap.Error):  # the library's: fewer than two waypoints
        hmap.sim.car_path(np.zeros((1, 3)))
    with pytest.raises(ValueError, match="unknown route"):
        hmap.sim.route("moon")
    with pytest.raises(ValueError, match="axes must be"):
        hmap.sim.noisy_odometry(np.tile(np.eye(4), (2, 1, 1)), axes="xy")
    with pytest.raises(hmap.Error, match=r"objects\[0\]"):
        hmap.sim.Scene.from_json('{"objects": [{"type": "box", "size": [1, 2]}]}')


def test_scans_run_without_the_gil():
    # While an HDL-64 scan of the parking (tens of ms) runs in a thread, this thread keeps running
    # Python: the longest pause it sees is well below the scan's time. Held GIL: a pause as long as
    # the scan, in every attempt; a busy machine may pause it once, so three attempts.
    scene = hmap.sim.Scene("parking")
    T = hmap.sim.car_path(hmap.sim.route("parking")).poses[300]
    lidar = hmap.sim.Sensor("hdl64", noise=False)
    start = time.perf_counter()
    alone = lidar.scan(scene, T)["points"]
    duration = time.perf_counter() - start
    results = []
    for _ in range(3):
        done = threading.Event()
        worker = threading.Thread(target=lambda: (results.append(lidar.scan(scene, T)["points"]), done.set()))
        longest, last = 0.0, time.perf_counter()
        worker.start()
        while not done.is_set():
            now = time.perf_counter()
            longest, last = max(longest, now - last), now
        worker.join()
        if longest < 0.5 * duration:
            break
    assert longest < 0.5 * duration, (longest, duration)
    for r in results:
        np.testing.assert_array_equal(r, alone)   # noise-free: the same scan every time


def test_two_threads_two_sensors_equal_one_thread():
    scene = hmap.sim.Scene("office")
    path = hmap.sim.diff_drive_path(hmap.sim.route("office"))
    def run(seed, out):
        lidar = hmap.sim.Sensor("vlp16", seed=seed)
        out.extend(lidar.scan(scene, path.poses[k], path.times[k])["points"] for k in range(3))
    expected = {seed: [] for seed in (1, 2)}
    for seed in expected:
        run(seed, expected[seed])
    got = {seed: [] for seed in (1, 2)}
    threads = [threading.Thread(target=run, args=(seed, got[seed])) for seed in got]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for seed in expected:
        for a, b in zip(expected[seed], got[seed], strict=True):
            np.testing.assert_array_equal(a, b)


def test_simulate_mount_yaw(tmp_path):
    # A lidar mounted turned by 20°: the CLI's files and the library's recording agree, and its poses
    # are the straight mounting's turned about the sensor's own z axis.
    out = simulate_cli(tmp_path, "--scene", "parking", "--sensor", "vlp16", "--mount-yaw", "20")
    rec = hmap.sim.simulate("parking", "vlp16", frames=2, truth_spacing=2, mount_yaw=20.0)
    straight = hmap.sim.simulate("parking", "vlp16", frames=2, truth_spacing=2)
    np.testing.assert_allclose(read_kitti_poses(out / "poses.txt"), rec["poses"], atol=1e-9)
    a = np.radians(20.0)
    turn = np.array([[np.cos(a), -np.sin(a), 0, 0], [np.sin(a), np.cos(a), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    np.testing.assert_allclose(rec["poses"], straight["poses"] @ turn, atol=1e-12)
    cli = np.fromfile(out / "velodyne" / "000000.bin", dtype="<f4").reshape(-1, 4)[:, :3]
    np.testing.assert_array_equal(rec["scans"][0], cli)
    with pytest.raises(hmap.Error, match="--mount-yaw turns a spinning lidar"):
        hmap.sim.simulate("office", "kinect", frames=1, mount_yaw=10.0)
    r = subprocess.run([str(cli_or_skip()), "simulate", "--sensor", "vlp16", "--mount-yaw", "181", "--out",
                        str(tmp_path / "b")], capture_output=True, text=True)
    assert r.returncode == 2 and "--mount-yaw must be within [-180, 180] deg (got 181 deg)" in r.stderr, r.stderr
