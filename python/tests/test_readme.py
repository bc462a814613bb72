"""The README's Python examples run as written (on the recorded balm_os0 and kitti_hdl64_seq16 scans)."""

import os
import pathlib
import re
import runpy
import subprocess

import pytest

from conftest import REPO, data_dir, require_data


def readme_python_blocks():
    text = (REPO / "README.md").read_text()
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_readme_python_example_runs(tmp_path, monkeypatch, capsys):
    require_data("balm_os0")
    blocks = readme_python_blocks()
    assert len(blocks) == 3
    # Written for the repository root, where ../shared/data is; run in a scratch folder instead.
    code = blocks[0].replace("../shared/data", str(data_dir()))
    script = tmp_path / "example.py"
    script.write_text(code)
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(script), run_name="__main__")
    out = capsys.readouterr().out
    assert re.match(r"\d+ \[\(", out) and "Grid2D(" in out, out
    assert (tmp_path / "balm_os0_py.hmap").stat().st_size > 0


def test_readme_slam_example_runs(tmp_path, monkeypatch, capsys):
    data = require_data("kitti_hdl64_seq16")
    cli = pathlib.Path(os.environ.get("HMAP_BIN", ""))
    if not cli.is_file():
        pytest.skip("the hmap tool is not built (HMAP_BIN)")
    code = readme_python_blocks()[1].replace("../shared/data", str(data_dir()))
    monkeypatch.chdir(tmp_path)
    # The CLI run the README has the reader start with.
    subprocess.run([str(cli), "slam", "--kitti", str(data), "--scans", "5", "--out", "out/slam_k5"], check=True,
                   capture_output=True)
    script = tmp_path / "example.py"
    script.write_text(code)
    runpy.run_path(str(script), run_name="__main__")
    assert float(capsys.readouterr().out) < 1e-9


def test_readme_plot_example_runs(tmp_path, monkeypatch):
    require_data("balm_os0")
    code = readme_python_blocks()[2].replace("../shared/data", str(data_dir()))
    monkeypatch.chdir(tmp_path)
    script = tmp_path / "example.py"
    script.write_text(code)
    runpy.run_path(str(script), run_name="__main__")
    import matplotlib.image

    image = matplotlib.image.imread(tmp_path / "balm_os0_grid.png")
    assert image.shape[:2] == (480, 640)  # matplotlib's default figure, 6.4 x 4.8 in at 100 dpi
    assert len({tuple(c) for c in (image.reshape(-1, image.shape[2]) * 255).round().astype(int)}) > 50
