"""examples/python: each script runs as a user would run it, and what it writes is checked."""

import json
import os
import subprocess
import sys

import numpy as np

import hmap
from conftest import REPO, data_dir, require_data
from test_writers import read_pgm, read_png

EXAMPLES = REPO / "examples" / "python"


def run(script, *args):
    return subprocess.run([sys.executable, str(EXAMPLES / script), *map(str, args)], check=True, capture_output=True,
                          text=True, env=dict(os.environ)).stdout


def test_simulate_and_map(tmp_path):
    out = run("simulate_and_map.py", "--out", tmp_path, "--frames", "20")
    summary = json.loads((tmp_path / "summary.json").read_text())
    m = hmap.Map.load(tmp_path / "map.hmap")
    stats = m.stats()
    assert f"{stats['cells']} cells, {stats['hvoxels']} HVoxels" in out
    assert summary["cells"] == stats["cells"] > 1000 and summary["hvoxels"] == stats["hvoxels"]
    grid = m.grid()
    image = read_png(tmp_path / "grid.png")
    assert list(image.shape) == summary["grid_shape"] + [3] == list(grid.probability.shape) + [3]
    # North up: the image's bottom row is the grid's row 0; occupied dark, free light, unknown grey.
    p = grid.probability[::-1]
    assert np.all(image[np.isnan(p)] == 128)
    known = ~np.isnan(p)
    np.testing.assert_array_equal(image[known][:, 0], np.round((1.0 - p[known]) * 255))
    occupied, free = p > 0.65, p <= 0.35   # the PGM's thresholds for occupied; free by one ground pass
    assert occupied.sum() > 10 and free.sum() > 1000
    assert image[occupied].max() < 90 and image[free].min() > 160
    pixels = read_pgm(tmp_path / "grid.pgm")
    assert (pixels == 0).sum() > 0 and (pixels == 254).sum() > 0


def test_slam_and_evaluate(tmp_path):
    out = run("slam_and_evaluate.py", "--out", tmp_path, "--frames", "20", "--stride", "3")
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["scans"] == 20
    truth = hmap.io.read_poses(tmp_path / "seq" / "poses.txt")
    estimate = hmap.io.read_poses(tmp_path / "poses.txt")
    assert estimate.shape == truth.shape == (20, 4, 4)
    # SLAM starts at the first true pose: the position exactly, the tilt fitted to the floor and
    # the walls (within 0.1 deg).
    np.testing.assert_allclose(estimate[0][:3, 3], truth[0][:3, 3], atol=1e-4)
    np.testing.assert_allclose(estimate[0][:3, :3], truth[0][:3, :3], atol=2e-3)
    again = hmap.eval.trajectory(truth, estimate)
    assert abs(again["ate_rmse_m"] - result["ate_rmse_m"]) < 1e-6  # poses.txt holds 9 digits
    # Scan matching beats the noisy odometry it starts from (fixed seed, so the same every run).
    assert result["ate_rmse_m"] < result["odometry_ate_rmse_m"]
    assert result["ate_rmse_m"] < 0.3
    assert f"SLAM on 20 scans: ATE {result['ate_rmse_m']:.3f} m" in out


def test_map_balm_plot(tmp_path):
    require_data("balm_os0")
    out = run("map_balm_plot.py", "--data", data_dir(), "--scans", "12", "--size", "640x480", "--out", tmp_path / "plot.png")
    assert "wrote" in out and "12 scans" in out
    image = plt_read(tmp_path / "plot.png")
    assert image.shape[:2] == (480, 640)  # the size asked for
    colours = {tuple(c) for c in image.reshape(-1, image.shape[2])}
    assert len(colours) > 50  # the grid, the path, text and antialiased lines: not a blank figure
    # The grid's three classes and the path's red are all there.
    assert {(0, 0, 0), (255, 255, 255), (205, 205, 205)} <= {c[:3] for c in colours}
    assert any(r > 180 and g < 60 and b < 60 for r, g, b in (c[:3] for c in colours))


def test_map_balm_plot_without_the_data(tmp_path):
    r = subprocess.run([sys.executable, str(EXAMPLES / "map_balm_plot.py"), "--data", tmp_path / "nowhere", "--out",
                        tmp_path / "plot.png"], capture_output=True, text=True, env=dict(os.environ))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "nowhere/balm_os0 holds no velodyne/ scans" in lines[0], r.stderr
    assert not (tmp_path / "plot.png").exists()


def plt_read(path):
    """A PNG as an (H, W, channels) uint8 array, read by matplotlib (RGBA from savefig)."""
    import matplotlib.image

    image = matplotlib.image.imread(path)
    return np.round(image * 255).astype(np.uint8) if image.dtype != np.uint8 else image
