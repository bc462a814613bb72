"""The README's Python example runs as written (on the recorded balm_os0 scans)."""

import pathlib
import re
import runpy

from conftest import REPO, data_dir, require_data


def readme_python_blocks():
    text = (REPO / "README.md").read_text()
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_readme_python_example_runs(tmp_path, monkeypatch, capsys):
    require_data("balm_os0")
    blocks = readme_python_blocks()
    assert len(blocks) == 1
    # Written for the repository root, where ../shared/data is; run in a scratch folder instead.
    code = blocks[0].replace("../shared/data", str(data_dir()))
    script = tmp_path / "example.py"
    script.write_text(code)
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(script), run_name="__main__")
    out = capsys.readouterr().out
    assert re.match(r"\d+ \[\(", out) and "Grid2D(" in out, out
    assert (tmp_path / "balm_os0_py.hmap").stat().st_size > 0
