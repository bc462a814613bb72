"""Shared fixtures: the hand-made scene and where the recorded data lives."""

import os
import pathlib

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def data_dir():
    """HMAP_DATA_DIR (set by CTest from CMake's HMAP_DATA_DIR), else ../shared/data beside the repo."""
    return pathlib.Path(os.environ.get("HMAP_DATA_DIR", REPO.parent / "shared" / "data"))


def require_data(name):
    path = data_dir() / name
    if not path.exists():
        pytest.skip(f"recorded data {path} is absent (set HMAP_DATA_DIR)")
    return path


# The scene of the mapping tests, in the sensor frame, the sensor 1 m above a floor:
#   a floor z = -1 over x, y in (-6, 6), a point every 5 cm, off the cell borders;
#   a wall in the cell x in [5.0, 5.2) (cell size 0.2), y in (-2, 2), from the floor (z = -1) up
#   to z = +1, a point every 5 cm on z: 4 y values x 41 z values = 164 points per wall cell.
CELL = 0.2
WALL_X = 5.1
WALL_Z = np.round(np.arange(41) * 0.05 - 1.0, 6)
WALL_POINTS_PER_CELL = 4 * len(WALL_Z)


def scene_points():
    g = np.arange(-120, 120) * 0.05 + 0.025                # -5.975 .. 5.975, never on a cell border
    fx, fy = np.meshgrid(g, g, indexing="ij")
    floor = np.stack([fx.ravel(), fy.ravel(), np.full(fx.size, -1.0)], axis=1)
    floor = floor[floor[:, 0] < 5.0]                        # the wall stands on the floor's edge
    wy = np.arange(-40, 40) * 0.05 + 0.025                  # -1.975 .. 1.975
    yy, zz = np.meshgrid(wy, WALL_Z, indexing="ij")
    wall = np.stack([np.full(yy.size, WALL_X), yy.ravel(), zz.ravel()], axis=1)
    return np.concatenate([floor, wall]).astype(np.float64)


def sensor_pose(height=1.0):
    T = np.eye(4)
    T[2, 3] = height
    return T


@pytest.fixture
def params():
    import hmap

    p = hmap.Params("outdoor")
    p.set("map.cell_size", CELL)
    return p


@pytest.fixture
def scene():
    return scene_points()


def cli_or_skip():
    """The built `hmap` tool (HMAP_BIN, set by CTest), or a skip when it is not built."""
    cli = pathlib.Path(os.environ.get("HMAP_BIN", ""))
    if not cli.is_file():
        pytest.skip("the hmap tool is not built (HMAP_BIN)")
    return cli
