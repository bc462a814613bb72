"""hmap.render: pictures as (H, W, 3) uint8 arrays. Each column of a tiny map lands on the pixel its
x, y give, coloured from its top as a twin of the colour map computes it, everything else black;
the pictures equal the CLI's PNGs pixel for pixel; bad arguments raise ValueError saying which."""

import subprocess

import numpy as np
import pytest

import hmap
from test_writers import cli_or_skip, read_png


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    """A hybrid map of three simulated VLP-16 scans of the office (seed 1), saved, and its path."""
    scene = hmap.sim.Scene("office")
    path = hmap.sim.diff_drive_path(hmap.sim.route("office"))
    lidar = hmap.sim.Sensor("vlp16", seed=1)
    params = hmap.Params("indoor")
    params.set("map.cell_size", 0.1)
    mapper = hmap.HybridMapper(params)
    poses = np.array([path.poses[k] for k in (0, 10, 20)])
    for k, T in zip((0, 10, 20), poses):
        mapper.integrate(lidar.scan(scene, T, path.times[k])["points"], T)
    saved = tmp_path_factory.mktemp("office") / "office.hmap"
    mapper.map.save(saved)
    return mapper.map, saved, poses


def height_colour(t):
    """The library's colour map (blue, cyan, green, yellow, red for t in [0, 1]), computed again."""
    t = min(max(t, 0.0), 1.0)
    ch = lambda v: int(np.floor(255.0 * min(max(v, 0.0), 1.0) + 0.5))  # lround: halves away from 0
    return ch(1.5 - abs(4 * t - 3)), ch(1.5 - abs(4 * t - 2)), ch(1.5 - abs(4 * t - 1))


@pytest.fixture(scope="module")
def tiny():
    """Two posts of points seen from a sensor at 1 m: cell size 0.5 m, one post 1 m tall at
    (1.25, 0.25), one 2 m tall at (2.25, 1.75)."""
    params = hmap.Params("outdoor")
    params.set("map.cell_size", 0.5)
    z = np.arange(0.02, 1.0, 0.04)
    posts = [np.column_stack([np.full(z.size, 1.25), np.full(z.size, 0.25), z]),
             np.column_stack([np.full(2 * z.size, 2.25), np.full(2 * z.size, 1.75), np.concatenate([z, z + 1.0])])]
    mapper = hmap.Mapper(params)
    T = np.eye(4)
    T[2, 3] = 1.0
    pts = np.concatenate(posts) - [0.0, 0.0, 1.0]  # in the sensor frame
    mapper.integrate(pts, T)
    return mapper.map


def test_tiny_map_each_column_at_its_pixel_in_its_colour_unknown_black(tiny):
    cols = tiny.hvoxels()
    assert len(np.unique(cols[["i", "j"]])) == 2
    image, vp = hmap.render.top(tiny, z_low=0.0, z_high=2.0)
    assert image.dtype == np.uint8 and image.shape == (vp.height, vp.width, 3)
    assert vp.m_per_px == 0.5  # one pixel per cell
    # The map spans its cells' extents: x in [1.0, 2.5], y in [0.0, 2.0].
    assert vp.extent == pytest.approx((1.0, 2.5, 0.0, 2.0))
    assert vp.origin == pytest.approx((1.0, 0.0))
    expected = np.zeros_like(image)
    for x, y in ((1.25, 0.25), (2.25, 1.75)):
        top = tiny.column(x, y)["z_max"].max()
        col, row = vp.pixel(x, y)
        expected[row, col] = height_colour((top - 0.0) / 2.0)
    assert vp.pixel(1.25, 0.25) == (0, 3) and vp.pixel(2.25, 1.75) == (2, 0)
    np.testing.assert_array_equal(image, expected)
    assert tuple(image[0, 2]) != tuple(image[3, 0])  # two heights, two colours


def test_draw_path_over_a_top_view(tiny):
    image, vp = hmap.render.top(tiny)
    poses = np.repeat(np.eye(4)[None], 2, axis=0)
    poses[0, :2, 3] = (1.25, 1.25)
    poses[1, :2, 3] = (2.25, 1.25)
    drawn = hmap.render.draw_path(image, vp, poses, colour=(10, 20, 30))
    assert drawn.shape == image.shape and drawn is not image
    col, row = vp.pixel(1.25, 1.25)
    assert tuple(drawn[row, col]) == (10, 20, 30)
    assert tuple(image[row, col]) == (0, 0, 0)  # the input is left as it was
    # A list of 4x4 poses draws the same.
    np.testing.assert_array_equal(hmap.render.draw_path(image, vp, list(poses), colour=(10, 20, 30)), drawn)


def test_shapes_and_the_legend_beside_the_map(office):
    m, _, poses = office
    for layer in ("height", "occupancy", "ground"):
        image, vp = hmap.render.top(m, layer=layer, max_pixels=200)
        assert image.dtype == np.uint8 and image.shape == (vp.height, vp.width, 3) and max(image.shape[:2]) <= 200
        with_legend, vp2 = hmap.render.top(m, layer=layer, max_pixels=200, legend=True)
        assert vp2.extent == vp.extent and with_legend.shape[1] > vp.width
        np.testing.assert_array_equal(with_legend[:vp.height, :vp.width], image)
    g, vp = hmap.render.grid(m, max_pixels=200, paths=poses)
    greys = {tuple(c) for c in g.reshape(-1, 3)}
    assert {(0, 0, 0), (255, 255, 255), (205, 205, 205), (0, 90, 255)} <= greys  # the path blue
    ob = hmap.render.oblique(m, max_pixels=150)
    assert ob.dtype == np.uint8 and ob.ndim == 3 and ob.shape[2] == 3 and max(ob.shape[:2]) <= 152  # a pixel of border
    assert len({tuple(c) for c in ob.reshape(-1, 3)}) > 20


def test_a_slam_map_without_a_kept_grid_gets_the_derived_one(office):
    m, saved, _ = office
    # A plain Mapper keeps no grid: the picture is the grid `hmap export --pgm` derives.
    mapper = hmap.Mapper(m.params)
    scene = hmap.sim.Scene("office")
    path = hmap.sim.diff_drive_path(hmap.sim.route("office"))
    lidar = hmap.sim.Sensor("vlp16", seed=1)
    mapper.integrate(lidar.scan(scene, path.poses[0], path.times[0])["points"], path.poses[0])
    assert mapper.map.grid() is None
    image, _ = hmap.render.grid(mapper.map, max_pixels=200)
    colours = {tuple(c) for c in image.reshape(-1, 3)}
    assert (255, 255, 255) in colours and (0, 0, 0) in colours


def test_equal_to_the_clis_pngs(office, tmp_path):
    cli = cli_or_skip()
    m, saved, poses = office
    traj = tmp_path / "poses.txt"
    traj.write_text("".join(" ".join(f"{v:.9g}" for v in T[:3].ravel()) + "\n" for T in poses))
    loaded = hmap.Map.load(saved)
    read_back = hmap.io.read_poses(traj)
    cases = [
        (["--max-pixels", "300"], hmap.render.top(loaded, max_pixels=300, legend=True)[0]),
        (["--layer", "occupancy", "--trajectory", str(traj), "--max-pixels", "300"],
         hmap.render.grid(loaded, max_pixels=300, paths=[read_back], labels=["path poses.txt"], legend=True)[0]),
        (["--layer", "ground", "--z-low", "0", "--z-high", "1.5"],
         hmap.render.top(loaded, layer="ground", z_low=0.0, z_high=1.5, legend=True)[0]),
        (["--view", "oblique", "--max-pixels", "400"], hmap.render.oblique(loaded, max_pixels=400)),
    ]
    for k, (args, image) in enumerate(cases):
        out = tmp_path / f"cli{k}.png"
        subprocess.run([str(cli), "render", str(saved), "--out", str(out), *args], check=True, capture_output=True)
        hmap.io.write_png(tmp_path / f"py{k}.png", image)
        assert (tmp_path / f"py{k}.png").read_bytes() == out.read_bytes(), args
    # And decoded without the library: the CLI's occupancy picture, pixel for pixel.
    np.testing.assert_array_equal(read_png(tmp_path / "cli1.png"), cases[1][1])


def test_pvox_pictures(tmp_path):
    grid = hmap.pvox.VoxelMap(0.1)
    xs = np.arange(0.05, 3.0, 0.1)
    floor = np.array([(x, y, 0.05) for x in xs for y in xs])
    T = np.eye(4)
    T[2, 3] = 1.0  # the sensor 1 m above the floor
    for _ in range(5):
        grid.insert(floor - [0.0, 0.0, 1.0], T)
    for view in ("top", "iso"):
        image = hmap.render.pvox(grid, view=view, max_pixels=120)
        assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3
        assert len({tuple(c) for c in image.reshape(-1, 3)}) > 3
    with pytest.raises(hmap.Error, match="no occupied voxel"):
        hmap.render.pvox(hmap.pvox.VoxelMap(0.1))
    with pytest.raises(ValueError, match="view must be 'top' or 'iso'"):
        hmap.render.pvox(grid, view="side")


def test_bad_arguments_raise_value_error_saying_which(tiny):
    image, vp = hmap.render.top(tiny)
    for bad in (0, -3, 20001):
        with pytest.raises(ValueError, match=r"max_pixels = -?\d+ is out of its range \[1, 20000\]"):
            hmap.render.top(tiny, max_pixels=bad)
        with pytest.raises(ValueError, match="max_pixels"):
            hmap.render.oblique(tiny, max_pixels=bad)
    with pytest.raises(ValueError, match=r"paths must be an \(N, 4, 4\) array of poses or a sequence of them"):
        hmap.render.top(tiny, paths=np.zeros((3, 4)))
    with pytest.raises(ValueError, match=r"paths\[1\] must be an \(N, 4, 4\) array of poses"):
        hmap.render.top(tiny, paths=[np.eye(4)[None], np.zeros((2, 3, 3))])
    with pytest.raises(ValueError, match="paths must be"):
        hmap.render.top(tiny, paths="poses.txt")
    with pytest.raises(ValueError, match=r"poses must be an \(N, 4, 4\) array"):
        hmap.render.draw_path(image, vp, np.eye(4))
    with pytest.raises(ValueError, match=r"image must have shape \(H, W, 3\)"):
        hmap.render.draw_path(image[:, :, 0], vp, np.eye(4)[None])
    with pytest.raises(ValueError, match="colour must be three numbers in"):
        hmap.render.draw_path(image, vp, np.eye(4)[None], colour=(0, 300, 0))
    with pytest.raises(ValueError, match="layer must be 'height', 'occupancy' or 'ground'"):
        hmap.render.top(tiny, layer="heights")
    with pytest.raises(ValueError, match="labels: 2 given for 1 paths"):
        hmap.render.top(tiny, paths=np.eye(4)[None], labels=["a", "b"])
    with pytest.raises(ValueError, match="z_low / z_high must be finite"):
        hmap.render.top(tiny, z_low=float("nan"))
    with pytest.raises(hmap.Error, match="no ground patches"):
        hmap.render.top(tiny, layer="ground")
    with pytest.raises(hmap.Error, match="empty"):
        hmap.render.top(hmap.Mapper(hmap.Params()).map)
