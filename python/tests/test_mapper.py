"""hmap.Mapper / hmap.HybridMapper on a hand-made scene, and every bad input they refuse."""

import math
import threading

import numpy as np
import pytest

import hmap
from conftest import CELL, WALL_POINTS_PER_CELL, WALL_X, sensor_pose


def wall_map(params, points, mapper_type=hmap.Mapper):
    mapper = mapper_type(params)
    stats = mapper.integrate(points, sensor_pose())
    return mapper, stats


def test_wall_column_holds_one_hvoxel_of_the_walls_height(params, scene):
    mapper, stats = wall_map(params, scene)
    assert stats["points_in"] == len(scene)
    assert stats["dropped_non_finite"] == 0
    m = mapper.map
    col = m.column(WALL_X, 0.1)  # the cell x in [5.0, 5.2), y in [0, 0.2)
    assert col.dtype.names == ("z_min", "z_max", "count", "density")
    assert len(col) == 1
    # The sensor stands 1 m up: the wall spans z = 0 .. 2 m in the map frame.
    assert col["z_min"][0] == pytest.approx(0.0, abs=1e-6)
    assert col["z_max"][0] == pytest.approx(2.0, abs=1e-6)
    assert col["count"][0] == WALL_POINTS_PER_CELL
    # eq. (1): rho = K_m / (1 + exp(-K_n (|v| - d_min) / (h A))).
    x = 0.0005 * (WALL_POINTS_PER_CELL - 5) / (2.0 * CELL * CELL)
    assert col["density"][0] == pytest.approx(1.0 / (1.0 + math.exp(-x)), rel=1e-5)
    assert len(m.column(WALL_X, 5.0)) == 0  # beyond the wall's end (y < 2)


def test_occupied_inside_and_outside_the_wall(params, scene):
    m = wall_map(params, scene)[0].map
    queries = np.array([
        [WALL_X, 0.1, 1.0],    # inside the wall
        [5.01, -1.9, 0.05],    # inside, near its lower corner
        [WALL_X, 0.1, 2.5],    # above it
        [3.0, 0.1, 1.0],       # in front of it, in the air
        [WALL_X, 5.0, 1.0],    # beside its end
        [5.3, 0.1, 1.0],       # behind it
    ])
    assert m.occupied(queries).tolist() == [True, True, False, False, False, False]
    assert m.occupied(queries.astype(np.float32)).tolist() == [True, True, False, False, False, False]
    assert m.occupied(np.zeros((0, 3))).shape == (0,)


def test_raycast_meets_the_wall_and_the_floor(params, scene):
    """The wall's cell spans x in [5.0, 5.2), z 0 .. 2 (the sensor 1 m up): a level ray from the
    sensor meets it at x = 5.0; one straight down meets the floor's HVoxel top; one over the wall
    meets nothing. The points met are occupied and a step short of them is not."""
    m = wall_map(params, scene)[0].map
    origins = np.array([[0.0, 0.1, 1.0], [2.01, 0.11, 1.0], [0.0, 0.1, 3.0], [0.0, 0.1, 1.0]])
    directions = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -2.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    floor_top = m.column(2.01, 0.11)["z_max"].max()
    ranges, points = m.raycast(origins[:3], directions[:3], 50.0)
    assert ranges[0] == pytest.approx(5.0, abs=1e-9)
    assert ranges[1] == pytest.approx(1.0 - floor_top, abs=1e-6)
    assert np.isnan(ranges[2]) and np.isnan(points[2]).all()
    assert m.occupied(points[:2]).all()
    short = origins[:2] + (ranges[:2, None] - 1e-3) * directions[:2] / np.linalg.norm(directions[:2], axis=1)[:, None]
    assert not m.occupied(short).any()
    # One origin for many directions: a fan of level rays, each meets the wall where |y| < 2.
    angles = np.radians(np.arange(-30, 31, 5))
    fan = np.column_stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)])
    r, p = m.raycast(origins[0], fan, 50.0)
    ahead = np.abs(5.0 * np.tan(angles) + 0.1) < 1.9
    assert np.allclose(p[ahead, 0], 5.0) and np.allclose(r[ahead], 5.0 / np.cos(angles[ahead]))
    assert np.isnan(r[~ahead & (np.abs(angles) > np.radians(25))]).all()  # past the wall's ends: the floor is below
    assert np.isnan(m.raycast(origins[3], directions[3], 4.9)[0]).all()  # short of the wall
    with pytest.raises(ValueError, match="rows"):
        m.raycast(np.zeros((2, 3)), np.ones((3, 3)), 1.0)
    with pytest.raises(hmap.Error, match="max_range"):
        m.raycast(origins[0], directions[0], -1.0)
    with pytest.raises(hmap.Error, match="direction"):
        m.raycast(origins[0], np.zeros(3), 1.0)


def test_iterating_a_map_gives_each_cell_and_its_column(params, scene):
    m = wall_map(params, scene)[0].map
    cells = list(m)
    assert len(cells) == m.stats()["cells"]
    assert sum(len(col) for _, _, col in cells) == m.stats()["hvoxels"]
    assert [(i, j) for i, j, _ in cells] == sorted((i, j) for i, j, _ in cells)
    for i, j, col in cells[:: max(1, len(cells) // 50)]:
        np.testing.assert_array_equal(col, m.column((i + 0.5) * m.cell_size, (j + 0.5) * m.cell_size))


def test_stats_count_the_scene(params, scene):
    m = wall_map(params, scene)[0].map
    s = m.stats()
    assert s["cell_size"] == CELL
    assert s["hvoxels"] >= s["cells"] > 20 * 20
    (x0, y0, z0), (x1, y1, z1) = s["bounds"]
    # Cells span whole cell extents in x, y: the wall's cell ends at x = 5.2.
    assert x1 == pytest.approx(5.2) and z1 == pytest.approx(2.0, abs=1e-6)
    assert z0 == pytest.approx(0.0, abs=1e-6)  # the floor, 1 m under the sensor


def test_float32_float64_and_strided_inputs_give_the_same_map(params, scene, tmp_path):
    inputs = {
        "f64": scene,
        "f32": scene.astype(np.float32),
        "f32_strided": np.ascontiguousarray(np.hstack([scene, np.ones((len(scene), 1))]).astype(np.float32))[:, :3],
        "f64_fortran": np.asfortranarray(scene),
    }
    assert not inputs["f32_strided"].flags.c_contiguous
    saved = {}
    for name, pts in inputs.items():
        mapper, _ = wall_map(params, pts)
        mapper.map.save(tmp_path / f"{name}.hmap")
        saved[name] = (tmp_path / f"{name}.hmap").read_bytes()
    assert all(b == saved["f64"] for b in saved.values())


def test_save_load_round_trip(params, scene, tmp_path):
    mapper, _ = wall_map(params, scene, hmap.HybridMapper)
    m = mapper.map
    m.save(tmp_path / "a.hmap")
    back = hmap.Map.load(tmp_path / "a.hmap")
    assert back.stats() == m.stats()
    assert back.params == params
    np.testing.assert_array_equal(back.column(WALL_X, 0.1), m.column(WALL_X, 0.1))
    pts = m.recover_points()
    np.testing.assert_array_equal(back.recover_points(), pts)
    g, gb = m.grid(), back.grid()
    np.testing.assert_array_equal(g.probability, gb.probability)
    assert (g.origin, g.resolution) == (gb.origin, gb.resolution)
    for k, v in m.ground_patches().items():
        np.testing.assert_array_equal(back.ground_patches()[k], v)
    back.save(tmp_path / "b.hmap")
    assert (tmp_path / "a.hmap").read_bytes() == (tmp_path / "b.hmap").read_bytes()


def test_recover_points_sample_the_wall_column(params, scene):
    m = wall_map(params, scene)[0].map
    pts = m.recover_points(z_step=0.5)
    assert pts.dtype == np.float32 and pts.shape[1] == 3
    # The wall column (cell centre 5.1, 0.1) from 0 to 2 m every 0.5 m, both ends: 5 points.
    here = pts[(np.abs(pts[:, 0] - 5.1) < 1e-4) & (np.abs(pts[:, 1] - 0.1) < 1e-4)]
    np.testing.assert_allclose(np.sort(here[:, 2]), [0.0, 0.5, 1.0, 1.5, 2.0], atol=1e-6)
    assert m.occupied(pts.astype(np.float64)).all()
    with pytest.raises(ValueError, match=r"z_step = 0 m is out of its range"):
        m.recover_points(z_step=0.0)


def test_hybrid_grid_has_the_params_resolution_and_sees_the_wall(params, scene):
    mapper, stats = wall_map(params, scene, hmap.HybridMapper)
    assert stats["ground_accepted"] > 0
    m = mapper.map
    g = m.grid()
    assert g.resolution == CELL
    assert g.probability.dtype == np.float32 and g.probability.ndim == 2
    # The raster spans the observed cells: the floor's x, y in (-6, 5) and (-6, 6), and the wall's
    # cell x in [5.0, 5.2): 56 columns from x = -6, 60 rows from y = -6.
    assert g.origin == pytest.approx((-6.0, -6.0))
    assert g.probability.shape == (60, 56)
    ox, oy = g.origin

    def p_at(x, y):
        return g.probability[int((y - oy) // CELL), int((x - ox) // CELL)]

    assert p_at(WALL_X, 0.1) > 0.65   # the wall: occupied
    # Occupied are the wall's 20 cells (y in (-2, 2)) and only they: the last column, rows 20-39.
    occupied = np.argwhere(g.probability > 0.65)
    assert occupied[:, 1].tolist() == [55] * 20
    assert occupied[:, 0].tolist() == list(range(20, 40))
    assert p_at(3.0, 0.1) < 0.5       # the floor in front of it: free
    patches = m.ground_patches()
    n = len(patches["parent"])
    assert n == stats["ground_accepted"] + 1  # the root and the connected candidates
    assert patches["center"].shape == (n, 3) and patches["normal"].shape == (n, 3)
    np.testing.assert_allclose(patches["center"][:, 2], 0.0, atol=0.03)  # the floor at z = 0
    np.testing.assert_allclose(np.abs(patches["normal"][:, 2]), 1.0, atol=1e-3)
    assert hmap.Mapper(params).map.grid() is None


def test_map_is_live(params, scene):
    mapper = hmap.Mapper(params)
    m = mapper.map
    assert m.stats()["hvoxels"] == 0 and m.stats()["bounds"] is None
    mapper.integrate(scene, sensor_pose())
    assert m.stats()["hvoxels"] > 0


@pytest.mark.parametrize(
    "points, message",
    [
        (np.zeros((10, 2)), r"points must have shape \(N, 3\), got \(10, 2\)"),
        (np.zeros(3), r"points must have shape \(N, 3\), got \(3,\)"),
        (np.zeros((10, 3), dtype=np.int64), "points must hold float32 or float64, got dtype int64"),
        ([[1.0, 2.0, 3.0]], "points must be a numpy array of shape \\(N, 3\\), got list"),
        (np.array([[5, 0, 0], [5, 1, np.nan]], dtype=np.float64), r"points: row 1 is not finite \(5, 1, nan\)"),
        (np.array([[5, 0, np.inf]], dtype=np.float32), r"points: row 0 is not finite"),
        (np.array([[1e39, 0, 0]]), r"points: row 0 is not finite \(inf"),  # beyond float32
    ],
)
def test_bad_points_raise_value_error_naming_the_problem(params, points, message):
    mapper = hmap.Mapper(params)
    with pytest.raises(ValueError, match=message):
        mapper.integrate(points, np.eye(4))
    assert mapper.map.stats()["hvoxels"] == 0


@pytest.mark.parametrize(
    "pose, message",
    [
        (np.eye(3), "T_map_sensor must be a 4x4 matrix"),
        ("identity", "T_map_sensor must be a 4x4 matrix"),
        (np.diag([2.0, 2.0, 2.0, 1.0]), r"T_map_sensor: pose is not a rigid transform: its 3x3 part is not a rotation"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), r"not a rotation \(.*det = -1\)"),
        (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]], float), "its last row is 0 0 1 1"),
        (np.full((4, 4), np.nan), "T_map_sensor: pose is not finite"),
    ],
)
def test_bad_pose_raises_value_error(params, pose, message):
    with pytest.raises(ValueError, match=message):
        hmap.Mapper(params).integrate(np.zeros((1, 3)), pose)


def test_non_finite_points_dropped_on_request(params, scene):
    pts = scene.copy()
    pts[7] = np.nan
    stats = hmap.Mapper(params).integrate(pts, sensor_pose(), non_finite="drop")
    assert stats["dropped_non_finite"] == 1
    with pytest.raises(ValueError, match="non_finite must be 'raise' or 'drop'"):
        hmap.Mapper(params).integrate(pts, sensor_pose(), non_finite="keep")


def test_a_pose_almost_rigid_is_taken(params, scene):
    T = sensor_pose()
    T[0, 0] += 1e-5  # a 9-digit rotation from a file: orthonormalised, as read_poses does
    stats = hmap.Mapper(params).integrate(scene, T)
    assert stats["points_kept"] > 0


def test_two_threads_integrate_two_maps(params, scene, tmp_path):
    # The GIL is released while integrating: two mappers in two threads give the maps one thread gives.
    mappers = [hmap.Mapper(params), hmap.Mapper(params)]
    threads = [threading.Thread(target=lambda m=m: [m.integrate(scene, sensor_pose()) for _ in range(3)]) for m in mappers]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    alone = hmap.Mapper(params)
    for _ in range(3):
        alone.integrate(scene, sensor_pose())
    for k, m in enumerate(mappers + [alone]):
        m.map.save(tmp_path / f"{k}.hmap")
    data = [(tmp_path / f"{k}.hmap").read_bytes() for k in range(3)]
    assert data[0] == data[1] == data[2]


def test_hvoxels_lists_every_cell_once_by_cell(params, scene):
    m = wall_map(params, scene)[0].map
    h = m.hvoxels()
    assert h.dtype.names == ("i", "j", "z_min", "z_max", "count", "density")
    assert len(h) == m.stats()["hvoxels"]
    keys = np.stack([h["i"], h["j"]], axis=1)
    assert (np.diff(keys[:, 0]) >= 0).all()
    # The wall: cells i = 25 (x in [5.0, 5.2)), j = -10 .. 9 (y in (-2, 2)), each one HVoxel of 164 points.
    wall = h[h["i"] == 25]
    assert wall["j"].tolist() == list(range(-10, 10))
    assert (wall["count"] == WALL_POINTS_PER_CELL).all()
    for field in ("z_min", "z_max", "count", "density"):
        np.testing.assert_array_equal(wall[wall["j"] == 0][field], m.column(WALL_X, 0.1)[field])
    # The floor: one thin HVoxel at z = 0 per cell; the points in its cells count 16 (4 x 4 at 5 cm).
    floor = h[h["i"] < 25]
    np.testing.assert_allclose(floor["z_max"], 0.0, atol=1e-6)
    assert np.median(floor["count"]) == 16
