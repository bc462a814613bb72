"""hmap.slam.Slam: `hmap slam` scan by scan, the same poses as the CLI; hmap.params_for_scan."""

import subprocess
import threading

import numpy as np
import pytest

import hmap
from conftest import cli_or_skip, require_data, scene_points

SCANS = 5



def test_slam_poses_equal_the_cli_poses(tmp_path):
    """The first scans of kitti_hdl64_seq16: Slam.poses are what `hmap slam --kitti` writes."""
    data = require_data("kitti_hdl64_seq16")
    cli = cli_or_skip()
    out = tmp_path / "O"
    subprocess.run([str(cli), "slam", "--kitti", str(data), "--scans", str(SCANS), "--out", str(out)], check=True,
                   capture_output=True)
    cli_poses = np.loadtxt(out / "poses.txt").reshape(-1, 3, 4)

    scans = hmap.io.kitti_sequence(data, max_scans=SCANS)
    first, pose, stamp = next(scans)
    assert pose is None and stamp is None  # velodyne/ only: no poses.txt, no times.txt
    chosen = hmap.params_for_scan(first)   # no preset named: chosen from the scan, as the CLI does
    assert chosen["preset"] == "outdoor" and chosen["preset_reason"]
    assert chosen["adapted"] == []  # the HDL-64's rings are close: the preset's height gap stands
    slam = hmap.slam.Slam(chosen["params"])
    steps = [slam.process(first)]
    steps += [slam.process(points, stamp) for points, _, stamp in scans]

    assert slam.poses.shape == (SCANS, 4, 4) and slam.scans == SCANS
    np.testing.assert_allclose(slam.poses[:, :3, :], cli_poses, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(np.stack([s["T_map_sensor"] for s in steps]), slam.poses)
    assert not steps[0]["matched"]
    for s in steps[1:]:
        assert s["matched"] and s["converged"] and not s["skipped"]
        assert s["hvoxels_used"] > 100 and 0.0 < s["score"] <= 1.0
        assert s["observable"]["x"] and s["observable"]["yaw"]
        assert s["mapping"]["points_in"] > 100000
        # slam.wall_tilt_drift is on by default: KITTI's street walls (over a hundred per scan) turn
        # the tilt by under a quarter of a degree.
        assert 0.0 <= s["wall_tilt"][0] < 0.004 and s["wall_tilt"][1] >= 100
    # The map is SLAM's, live, and saves the bytes `hmap slam` writes.
    slam.map.save(tmp_path / "py.hmap")
    assert (tmp_path / "py.hmap").read_bytes() == (out / "map.hmap").read_bytes()


def test_params_for_scan_named_preset_and_overrides():
    points = scene_points()
    chosen = hmap.params_for_scan(points, "indoor", overrides=["map.max_range=4"], cell_size=0.1)
    assert chosen["preset"] == "indoor" and chosen["preset_reason"] is None
    assert chosen["params"].get("map.cell_size") == 0.1 and chosen["params"].get("map.max_range") == 4
    with pytest.raises(hmap.Error, match="map.cell_size"):
        hmap.params_for_scan(points, cell_size=-1)
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        hmap.params_for_scan(np.zeros((4, 2)))


def test_slam_on_the_hand_made_scene_stays_put(params):
    """The same scene twice from the same place: the second scan matches at the first's pose."""
    points = scene_points()
    slam = hmap.slam.Slam(params)
    first = slam.process(points)
    second = slam.process(points)
    assert not first["matched"] and second["matched"]
    np.testing.assert_allclose(second["T_map_sensor"], first["T_map_sensor"], atol=0.02)
    assert slam.map.stats()["hvoxels"] > 0 and slam.map.grid() is None
    assert set(first["observable"]) == {"x", "y", "z", "roll", "pitch", "yaw"}


def test_slam_guess_and_attitude_are_taken():
    params = hmap.Params("outdoor")
    slam = hmap.slam.Slam(params)
    T = np.eye(4)
    T[:3, 3] = [3.0, -2.0, 1.5]
    step = slam.process(scene_points(), attitude=T, guess=T)  # the first scan is put at the guess
    np.testing.assert_allclose(step["T_map_sensor"], T, atol=1e-12)
    assert not step["attitude_fit"]["ran"]


def test_slam_refuses_bad_input(params):
    slam = hmap.slam.Slam(params)
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        slam.process(np.zeros((10, 4)))
    with pytest.raises(ValueError, match="float32 or float64"):
        slam.process(np.zeros((10, 3), dtype=np.int32))
    bad = scene_points()
    bad[7] = np.nan
    with pytest.raises(ValueError, match="row 7 is not finite"):
        slam.process(bad)
    with pytest.raises(ValueError, match="times must be a 1-D array of 3 numbers"):
        slam.process(np.zeros((3, 3)), times=np.zeros(2))
    with pytest.raises(ValueError, match="guess: pose is not a rigid transform"):
        slam.process(scene_points(), guess=np.full((4, 4), 2.0))
    with pytest.raises(ValueError, match="non_finite"):
        slam.process(scene_points(), non_finite="keep")
    assert slam.scans == 0 and slam.poses.shape == (0, 4, 4)  # nothing was processed
    step = slam.process(bad, non_finite="drop")
    assert step["mapping"]["points_in"] == len(bad) - 1
    with pytest.raises(ValueError, match="before the first scan"):
        slam.start_at_height(1.0)


def test_slam_releases_the_gil(params):
    """Two SLAMs in two threads: both finish, each with the poses it would have alone."""
    points = scene_points()
    alone = hmap.slam.Slam(params)
    for _ in range(3):
        alone.process(points)
    slams = [hmap.slam.Slam(params) for _ in range(2)]

    def run(s):
        for _ in range(3):
            s.process(points)

    threads = [threading.Thread(target=run, args=(s,)) for s in slams]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for s in slams:
        np.testing.assert_array_equal(s.poses, alone.poses)


def test_slam_with_an_imu_gives_the_poses_of_hmap_slam_imu(tmp_path):
    """`hmap simulate --imu-rate` writes imu.txt beside the scans; `hmap slam --imu` and
    Slam(params, imu=hmap.io.read_imu(...)) given the same scans and stamps agree bit for bit. The
    gyro turns the yaw guess; slam.imu_tilt_weight (0 by default) makes the gravity the tilt's too."""
    cli = cli_or_skip()
    sim = tmp_path / "S"
    subprocess.run([str(cli), "simulate", "--scene", "parking", "--sensor", "vlp16", "--frames", "6", "--stride", "3",
                    "--imu-rate", "100", "--out", str(sim)], check=True, capture_output=True)
    out = tmp_path / "O"
    run = subprocess.run([str(cli), "slam", "--kitti", str(sim), "--imu", str(sim / "imu.txt"), "--set",
                          "slam.imu_tilt_weight=1", "--out", str(out)],
                         check=True, capture_output=True, text=True)
    assert "with the IMU's gravity as prior" in run.stdout
    cli_poses = np.loadtxt(out / "poses.txt").reshape(-1, 3, 4)

    imu = hmap.io.read_imu(sim / "imu.txt")
    assert imu["gyro"].shape == (len(imu["stamps"]), 3) and imu["orientation"] is None
    assert np.all(np.diff(imu["stamps"]) > 0) and np.allclose(np.linalg.norm(imu["accel"], axis=1), 9.81, atol=1.0)
    scans = hmap.io.kitti_sequence(sim)
    first, _, stamp = next(scans)
    slam = hmap.slam.Slam(hmap.params_for_scan(first, overrides=["slam.imu_tilt_weight=1"])["params"], imu=imu)
    steps = [slam.process(first, stamp)]
    steps += [slam.process(points, stamp) for points, _, stamp in scans]
    with open(out / "matches.csv") as f:
        header = f.readline().strip().split(",")
        cli_imu_used = [line.split(",")[header.index("imu")] == "1" for line in f]
    assert [s["imu_used"] for s in steps] == cli_imu_used and all(cli_imu_used)
    np.testing.assert_allclose(slam.poses[:, :3, :], cli_poses, rtol=0, atol=1e-9)
    slam.map.save(tmp_path / "py.hmap")
    assert (tmp_path / "py.hmap").read_bytes() == (out / "map.hmap").read_bytes()


def test_slam_imu_refuses_bad_samples_and_unstamped_scans(params, tmp_path):
    params.set("slam.imu_tilt_weight", 1.0)
    imu = {"stamps": np.array([0.0, 0.01, 0.02]), "gyro": np.zeros((3, 3)), "accel": np.tile([0, 0, 9.81], (3, 1))}
    slam = hmap.slam.Slam(params, imu=imu)
    with pytest.raises(ValueError, match="needs each scan's stamp"):
        slam.process(scene_points())
    assert slam.process(scene_points(), 0.015)["imu_used"]
    with pytest.raises(ValueError, match=r"imu: gyro must be an \(N, 3\) array"):
        hmap.slam.Slam(params, imu=dict(imu, gyro=np.zeros((2, 3))))
    with pytest.raises(ValueError, match="imu has no 'accel'"):
        hmap.slam.Slam(params, imu={"stamps": imu["stamps"], "gyro": imu["gyro"]})
    with pytest.raises(hmap.Error):
        hmap.slam.Slam(params, imu=dict(imu, stamps=np.array([0.0, 0.0, 0.02])))  # stamps must increase
    (tmp_path / "imu.txt").write_text("0 0 0 0 0 0 9.81\n0.01 0 0 0 0 0\n")
    with pytest.raises(hmap.InputError, match=r"imu\.txt.*line 2"):
        hmap.io.read_imu(tmp_path / "imu.txt")
    (tmp_path / "imu.txt").write_text("0 0 0 0 0 0 9.81 0 0 0 1\n0.01 0.1 0 0 0 0 9.81 0 0 0 2\n")
    read = hmap.io.read_imu(tmp_path / "imu.txt")
    np.testing.assert_array_equal(read["orientation"], [[0, 0, 0, 1], [0, 0, 0, 1]])  # x y z w, normalised
    np.testing.assert_array_equal(read["gyro"][1], [0.1, 0, 0])


def test_slam_continues_a_saved_map_as_the_cli_does(tmp_path):
    """A second session localised in the first one's saved map (`hmap slam --continue`): the same
    poses from Python and the CLI, and within a few centimetres of one run over all the scans."""
    data = require_data("kitti_hdl64_seq16")
    cli = cli_or_skip()
    files = sorted((data / "velodyne").glob("*.bin"))[:6]
    subprocess.run([str(cli), "slam", *map(str, files[:3]), "--out", str(tmp_path / "A")], check=True, capture_output=True)
    subprocess.run([str(cli), "slam", *map(str, files[3:]), "--continue", str(tmp_path / "A" / "map.hmap"), "--out",
                    str(tmp_path / "B")], check=True, capture_output=True)
    subprocess.run([str(cli), "slam", *map(str, files), "--out", str(tmp_path / "AB")], check=True, capture_output=True)
    cli_poses = np.loadtxt(tmp_path / "B" / "poses.txt").reshape(-1, 3, 4)
    whole = np.loadtxt(tmp_path / "AB" / "poses.txt").reshape(-1, 3, 4)

    saved = hmap.Map.load(tmp_path / "A" / "map.hmap")
    scans = [hmap.io.read_cloud(f) for f in files[3:]]
    slam = hmap.slam.Slam(hmap.params_for_scan(scans[0])["params"], continue_map=saved)
    steps = [slam.process(points) for points in scans]
    np.testing.assert_allclose(slam.poses[:, :3, :], cli_poses, rtol=0, atol=1e-9)
    assert steps[0]["relocalised"] is not None and steps[1]["relocalised"] is None
    assert all(s["matched"] for s in steps)
    np.testing.assert_allclose(cli_poses[:, :3, 3], whole[3:, :3, 3], atol=0.05)
    # The saved map is built on, not changed: the loaded one still holds what it held, and saved
    # again it is the same file, its cell centroids included (format version 3).
    assert slam.map.stats()["hvoxels"] > saved.stats()["hvoxels"]
    # A live SLAM's map continues with its cell centroids too, and merge_maps keeps them (a map
    # merged with itself: the same cells, each weighed twice).
    assert 0 < saved.stats()["cell_centroids"] < slam.map.stats()["cell_centroids"]
    again = hmap.slam.Slam(hmap.params_for_scan(scans[0])["params"], continue_map=slam.map)
    assert again.map.stats()["cell_centroids"] == slam.map.stats()["cell_centroids"]
    assert hmap.merge_maps(saved, saved).stats()["cell_centroids"] == saved.stats()["cell_centroids"]
    saved.save(tmp_path / "A2.hmap")
    assert (tmp_path / "A2.hmap").read_bytes() == (tmp_path / "A" / "map.hmap").read_bytes()
    with pytest.raises(hmap.Error, match="search"):
        hmap.slam.Slam(hmap.Params("outdoor"), continue_map=saved, search=25.0)


def _planar(T):
    """x, y and yaw of a pose as a 4x4 (what the SLAM takes of an odometry pose)."""
    yaw = np.arctan2(T[1, 0], T[0, 0])
    M = np.eye(4)
    M[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    M[:2, 3] = T[:2, 3]
    return M


def test_slam_closes_a_loop_as_the_cli_does(tmp_path):
    """Once around a block of the simulated town with noisy odometry: Slam.close_loops closes the
    loops `hmap slam` closes, corrects the poses as it does, and its rebuilt map holds the CLI's."""
    cli = cli_or_skip()
    seq = tmp_path / "L"
    subprocess.run([str(cli), "simulate", "--scene", "city", "--route", "loop", "--route-km", "0.2", "--sensor", "vlp16",
                    "--stride", "10", "--out", str(seq)], check=True, capture_output=True)
    out = tmp_path / "O"
    run = subprocess.run([str(cli), "slam", "--kitti", str(seq), "--odometry", str(seq / "odometry.txt"), "--out",
                          str(out)], check=True, capture_output=True, text=True)
    cli_poses = np.loadtxt(out / "poses.txt").reshape(-1, 3, 4)
    cli_loops = np.atleast_2d(np.loadtxt(out / "loop_closures.csv", delimiter=",", skiprows=1))

    odometry = hmap.io.read_poses(seq / "odometry.txt")
    frames = list(hmap.io.kitti_sequence(seq))
    scans = [points for points, _, _ in frames]
    slam = hmap.slam.Slam(hmap.params_for_scan(scans[0])["params"])
    slam.start_at_height(odometry[0][2, 3])  # as the CLI does with --odometry
    for k, (points, _, stamp) in enumerate(frames):
        guess = odometry[0] if k == 0 else _planar(slam.poses[-1]) @ np.linalg.inv(_planar(odometry[k - 1])) @ _planar(odometry[k])
        slam.process(points, stamp, guess=guess)
    before = slam.poses.copy()
    read = []

    def read_scan(k):
        read.append(k)
        return scans[k]

    closed = slam.close_loops(read_scan)
    assert len(closed["closures"]) == len(cli_loops) > 0
    for c, row in zip(closed["closures"], cli_loops):
        assert (c["scan_old"], c["scan_new"]) == (row[2], row[3])
        assert c["score"] >= 0.4
    np.testing.assert_allclose(closed["poses"][:, :3, :], cli_poses, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(slam.poses, closed["poses"])  # Slam.poses are the corrected ones now
    # The loop moved them (by 2.8 cm at the end with the default centroids; 0.1 m and more with the
    # paper's cell centres, slam.hvoxel_centroids 0).
    assert np.abs(closed["poses"][:, :3, 3] - before[:, :3, 3]).max() > 0.01
    r = closed["rebuild"]
    assert not r["whole"]  # the sim's scans carry no per-point time: nothing was merged deskewed
    assert 0 < r["scans_moved"] <= len(scans) and r["scans_integrated"] == len(read)
    assert f"{r['scans_moved']} of {len(scans)} scans moved" in run.stdout
    cli_map = hmap.Map.load(out / "map.hmap").stats()
    assert closed["map"].stats()["cells"] == cli_map["cells"]
    assert closed["map"].stats()["hvoxels"] == cli_map["hvoxels"]
    # The cell centroids were summed again at the corrected poses where the map was rebuilt, and go
    # with it (loop_closure_test.cpp checks their values), in the CLI's file and in Python's.
    assert 0 < cli_map["cell_centroids"] == closed["map"].stats()["cell_centroids"]
    closed["map"].save(tmp_path / "P.hmap")
    assert hmap.Map.load(tmp_path / "P.hmap").stats()["cell_centroids"] == cli_map["cell_centroids"]
    with pytest.raises(ValueError, match="closed already"):
        slam.close_loops(read_scan)
    params = hmap.Params("outdoor")
    params.set("slam.loop_closure", 0)
    off = hmap.slam.Slam(params)
    with pytest.raises(ValueError, match="loop closure is off"):
        off.close_loops(read_scan)


def test_a_depth_frame_is_levelled_by_the_floor_under_it(tmp_path):
    """The first 7-Scenes frames: floor_under_sensor about -y and Slam.start_with_up give the poses of
    `hmap slam --rgbd --attitude-from scans` (the frames' poses, the ground truth, left alone)."""
    data = require_data("rgbd_7scenes")
    cli = cli_or_skip()
    out = tmp_path / "O"
    subprocess.run([str(cli), "slam", "--rgbd", str(data), "--scans", "3", "--attitude-from", "scans",
                    "--no-loop-closure", "--out", str(out)], check=True, capture_output=True)
    cli_poses = np.loadtxt(out / "poses.txt").reshape(-1, 3, 4)
    frames = [points for points, _, _ in hmap.io.rgbd_sequence(data, max_frames=3)]
    floor = hmap.io.floor_under_sensor(frames[0])
    assert floor is not None and 0.5 < floor["sensor_height"] < 1.0 and floor["inliers"] > 10000
    assert abs(np.linalg.norm(floor["up"]) - 1.0) < 1e-9
    assert hmap.io.floor_under_sensor(frames[0], prior_up=(0.0, 0.0, 1.0)) is None  # +z: the camera's forward
    params = hmap.params_for_scan(frames[0])["params"]
    params.set("slam.loop_closure", 0)
    slam = hmap.slam.Slam(params)
    slam.start_with_up(floor["up"])
    for points in frames:
        slam.process(points)
    np.testing.assert_allclose(slam.poses[:, :3, :], cli_poses, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="before the first scan"):
        slam.start_with_up((0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="finite and non-zero"):
        hmap.slam.Slam(params).start_with_up((0.0, 0.0, 0.0))
