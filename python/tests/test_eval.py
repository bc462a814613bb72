"""hmap.eval.trajectory: known errors on hand-made poses, and the numbers of `hmap eval traj --json`."""

import json
import math
import os
import pathlib
import subprocess

import numpy as np
import pytest

import hmap


def line_poses(n=20, step=1.0):
    """n poses along x, one every `step` metres, turning slowly about z."""
    poses = np.tile(np.eye(4), (n, 1, 1))
    for k in range(n):
        a = 0.02 * k
        poses[k, :2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
        poses[k, :3, 3] = [k * step, 0.1 * k * k * step / n, 0.0]
    return poses


def test_constant_offset_gives_its_length_as_ate():
    truth = line_poses()
    estimate = truth.copy()
    estimate[:, :3, 3] += [0.3, -0.4, 0.0]  # 0.5 m everywhere, in the world frame
    m = hmap.eval.trajectory(truth, estimate)
    assert m["frames"] == 20
    for key in ("ate_rmse_m", "ate_mean_m", "ate_median_m", "ate_max_m"):
        assert m[key] == pytest.approx(0.5, abs=1e-12)
    # The alignment removes the offset; relative motion is untouched by a world-frame shift.
    assert m["ate_rmse_aligned_m"] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(m["T_truth_estimate"][:3, 3], [-0.3, 0.4, 0.0], atol=1e-9)
    assert m["rpe_frame_trans_rmse_m"] == pytest.approx(0.0, abs=1e-12)
    assert m["rpe_frame_rot_rmse_deg"] == pytest.approx(0.0, abs=1e-9)
    assert m["segment_lengths"] == "fraction_of_path"  # 19 m of path: shorter than KITTI's 100 m


def test_same_trajectory_scores_zero():
    truth = line_poses()
    m = hmap.eval.trajectory(truth, truth)
    assert m["ate_rmse_m"] == 0.0 and m["rpe_trans_pct"] == pytest.approx(0.0, abs=1e-12)
    assert m["path_length_m"] > 19.0 and len(m["per_length"]) == len(m["segment_lengths_m"]) == 8


def test_bad_trajectories_are_refused():
    truth = line_poses()
    with pytest.raises(ValueError, match="estimate holds 19 poses, truth holds 20"):
        hmap.eval.trajectory(truth, truth[:19])
    with pytest.raises(ValueError, match=r"\(N, 4, 4\)"):
        hmap.eval.trajectory(truth[:, :3, :], truth[:, :3, :])
    broken = truth.copy()
    broken[3, 0, 0] = 5.0
    with pytest.raises(ValueError, match=r"estimate\[3\]: pose is not a rigid transform"):
        hmap.eval.trajectory(truth, broken)
    with pytest.raises(hmap.Error):
        hmap.eval.trajectory(truth[:1], truth[:1])  # the library's: fewer than 2 poses


def write_kitti(path, poses):
    np.savetxt(path, poses[:, :3, :].reshape(len(poses), 12), fmt="%.17g")


def test_equals_the_cli_json(tmp_path):
    cli = pathlib.Path(os.environ.get("HMAP_BIN", ""))
    if not cli.is_file():
        pytest.skip("the hmap tool is not built (HMAP_BIN)")
    truth = line_poses(60, 2.5)  # 147 m: KITTI's 100 m segments exist
    rng = np.random.default_rng(7)
    estimate = truth.copy()
    estimate[:, :3, 3] += np.cumsum(rng.normal(0, 0.05, (60, 3)), axis=0)
    write_kitti(tmp_path / "gt.txt", truth)
    write_kitti(tmp_path / "est.txt", estimate)
    out = subprocess.run([str(cli), "eval", "traj", "--gt", str(tmp_path / "gt.txt"), "--est",
                          str(tmp_path / "est.txt"), "--json"], check=True, capture_output=True, text=True).stdout
    expected = json.loads(out)
    m = hmap.eval.trajectory(hmap.io.read_poses(tmp_path / "gt.txt"), hmap.io.read_poses(tmp_path / "est.txt"))
    assert expected["segment_lengths"] == m["segment_lengths"] == "kitti"
    for key, value in expected.items():
        if key == "per_length":
            assert len(value) == len(m[key])
            for a, b in zip(value, m[key]):
                for k2, v2 in a.items():
                    assert (math.nan if v2 is None else v2) == pytest.approx(b[k2], rel=1e-12, nan_ok=True), k2
        elif not isinstance(value, str):
            assert (math.nan if value is None else value) == pytest.approx(m[key], rel=1e-12, nan_ok=True), key


def test_star_import_keeps_the_builtin_eval():
    scope = {}
    exec("from hmap import *", scope)
    assert "eval" not in scope and hmap.eval.trajectory is not None
