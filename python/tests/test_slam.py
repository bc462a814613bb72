"""hmap.slam.Slam: `hmap slam` scan by scan, the same poses as the CLI; hmap.params_for_scan."""

import os
import pathlib
import subprocess
import threading

import numpy as np
import pytest

import hmap
from conftest import require_data, scene_points

SCANS = 5


def cli_or_skip():
    cli = pathlib.Path(os.environ.get("HMAP_BIN", ""))
    if not cli.is_file():
        pytest.skip("the hmap tool is not built (HMAP_BIN)")
    return cli


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
