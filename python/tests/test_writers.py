"""The writers of hmap.io (`hmap export`'s PLY, PGM + YAML, .bt, and PNG): equal to the CLI's files
for the same map, decoded and checked against the map by hand, and their errors."""

import struct
import subprocess
import zlib

import numpy as np
import pytest

import hmap
from conftest import cli_or_skip



@pytest.fixture(scope="module")
def office(tmp_path_factory):
    """A hybrid map of three simulated VLP-16 scans of the office (seed 1), live and saved."""
    scene = hmap.sim.Scene("office")
    path = hmap.sim.diff_drive_path(hmap.sim.route("office"))
    lidar = hmap.sim.Sensor("vlp16", seed=1)
    params = hmap.Params("indoor")
    params.set("map.cell_size", 0.1)
    mapper = hmap.HybridMapper(params)
    for k in (0, 10, 20):
        mapper.integrate(lidar.scan(scene, path.poses[k], path.times[k])["points"], path.poses[k])
    saved = tmp_path_factory.mktemp("office") / "office.hmap"
    mapper.map.save(saved)
    return mapper, saved


def read_ply(path):
    """A binary little-endian PLY as written by ply_export: vertices (x, y, z float, r, g, b uchar)."""
    data = path.read_bytes()
    header, _, body = data.partition(b"end_header\n")
    lines = header.decode().splitlines()
    assert lines[:2] == ["ply", "format binary_little_endian 1.0"]
    n = next(int(l.split()[2]) for l in lines if l.startswith("element vertex"))
    faces = next((int(l.split()[2]) for l in lines if l.startswith("element face")), 0)
    vertices = np.frombuffer(body[:n * 15], dtype=np.dtype([("xyz", "<f4", 3), ("rgb", "u1", 3)]))
    return vertices, faces


def read_pgm(path):
    data = path.read_bytes()
    assert data[:3] == b"P5\n"
    fields, pos = [], 3
    while len(fields) < 3:
        end = data.index(b"\n", pos)
        line = data[pos:end]
        pos = end + 1
        if not line.startswith(b"#"):
            fields += [int(v) for v in line.split()]
    w, h, maxval = fields
    assert maxval == 255
    return np.frombuffer(data[pos:], dtype=np.uint8).reshape(h, w)


def read_png(path):
    """RGB 8-bit PNG, any of the five row filters (libpng chooses them), without a library."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, w = 8, b"", 0
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        chunk = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, color = struct.unpack(">IIBB", chunk[:10])
            assert (depth, color) == (8, 2)
        elif kind == b"IDAT":
            idat += chunk
        pos += 12 + n
    raw = zlib.decompress(idat)
    stride = w * 3
    out = np.zeros((h, stride), dtype=np.int32)
    prev = np.zeros(stride, dtype=np.int32)
    for r in range(h):
        f, line = raw[r * (stride + 1)], np.frombuffer(raw[r * (stride + 1) + 1:(r + 1) * (stride + 1)], np.uint8).astype(np.int32)
        row = np.zeros(stride, dtype=np.int32)
        for i in range(stride):
            a = row[i - 3] if i >= 3 else 0
            b = prev[i]
            c = prev[i - 3] if i >= 3 else 0
            if f == 0:
                pred = 0
            elif f == 1:
                pred = a
            elif f == 2:
                pred = b
            elif f == 3:
                pred = (a + b) // 2
            else:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else b if pb <= pc else c
            row[i] = (line[i] + pred) & 0xFF
        out[r] = row
        prev = row
    return out.reshape(h, w, 3).astype(np.uint8)


def test_files_equal_the_clis(office, tmp_path):
    cli = cli_or_skip()
    mapper, saved = office
    loaded = hmap.Map.load(saved)
    for args in (["--ply", "cli.ply"], ["--ply", "cli_pts.ply", "--points"], ["--pgm", "cli_grid"], ["--bt", "cli.bt"]):
        subprocess.run([str(cli), "export", str(saved), *[str(tmp_path / a) if a.startswith("cli") else a for a in args]],
                       check=True, capture_output=True)
    for tag, m in (("live", mapper.map), ("load", loaded)):
        hmap.io.write_ply(m, tmp_path / f"{tag}.ply")
        hmap.io.write_ply(m, tmp_path / f"{tag}_pts.ply", points=True)
        pgm = hmap.io.write_pgm(m, tmp_path / f"{tag}_grid")
        bt = hmap.io.write_bt(m, tmp_path / f"{tag}.bt")
        assert pgm["occupied"] > 100 and pgm["free"] > 1000
        assert bt["occupied_voxels"] > 1000 and bt["free_voxels"] > 0 and 0 < bt["leaves"] < bt["occupied_voxels"] + bt["free_voxels"]
        for name in (".ply", "_grid.pgm", ".bt"):
            assert (tmp_path / f"{tag}{name}").read_bytes() == (tmp_path / f"cli{name}").read_bytes(), (tag, name)
        yaml = (tmp_path / f"{tag}_grid.yaml").read_text().replace(f"{tag}_grid.pgm", "cli_grid.pgm")
        assert yaml == (tmp_path / "cli_grid.yaml").read_text()
    # The recovered points: the same file from the loaded map; the live map's tiles come in
    # another order (a hash map's), so the same points in another order.
    assert (tmp_path / "load_pts.ply").read_bytes() == (tmp_path / "cli_pts.ply").read_bytes()
    live, _ = read_ply(tmp_path / "live_pts.ply")
    cli_pts, _ = read_ply(tmp_path / "cli_pts.ply")
    key = lambda v: v["xyz"][np.lexsort(v["xyz"].T[::-1])]
    np.testing.assert_array_equal(key(live), key(cli_pts))


def test_ply_boxes_and_points_match_the_map(office, tmp_path):
    mapper, _ = office
    m = mapper.map
    hmap.io.write_ply(m, tmp_path / "boxes.ply")
    vertices, faces = read_ply(tmp_path / "boxes.ply")
    h = m.hvoxels()
    assert len(vertices) == 8 * len(h) and faces == 6 * len(h)
    lo, hi = m.stats()["bounds"]
    xyz = vertices["xyz"]
    assert xyz[:, 0].min() == pytest.approx(lo[0], abs=1e-5) and xyz[:, 0].max() == pytest.approx(hi[0], abs=1e-5)
    assert xyz[:, 2].min() <= h["z_min"].min() + 1e-5 and xyz[:, 2].max() >= h["z_max"].max() - 1e-5
    hmap.io.write_ply(m, tmp_path / "pts.ply", points=True, z_step=0.05)
    pts, faces = read_ply(tmp_path / "pts.ply")
    assert faces == 0
    np.testing.assert_array_equal(np.sort(pts["xyz"].view("f4,f4,f4").ravel()),
                                  np.sort(m.recover_points(0.05).view("f4,f4,f4").ravel()))
    hmap.io.write_points_ply(tmp_path / "cloud.ply", np.array([[1, 2, 3], [4, 5, 6]], dtype=np.float64))
    cloud, _ = read_ply(tmp_path / "cloud.ply")
    np.testing.assert_array_equal(cloud["xyz"], [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(cloud["rgb"][0], [0, 0, 255])   # lowest: blue
    np.testing.assert_array_equal(cloud["rgb"][1], [255, 0, 0])   # highest: red


def test_pgm_kept_grid_is_the_maps_grid(office, tmp_path):
    mapper, _ = office
    m = mapper.map
    info = hmap.io.write_pgm(m, tmp_path / "kept.pgm", grid="kept")  # a .pgm stem is accepted
    assert info["pgm"] == str(tmp_path / "kept.pgm") and info["yaml"] == str(tmp_path / "kept.yaml")
    pixels = read_pgm(tmp_path / "kept.pgm")
    g = m.grid()
    p = g.probability[::-1]                                # the PGM's first row is the northernmost
    assert pixels.shape == p.shape
    free_at_most = max(0.196, m.params.get("occupancy.ground_gain"))
    expected = np.full(p.shape, 205, dtype=np.uint8)
    expected[p > 0.65] = 0
    expected[p <= free_at_most] = 254
    np.testing.assert_array_equal(pixels, expected)
    assert info["occupied"] == int((p > 0.65).sum()) and info["free"] == int((p <= free_at_most).sum())
    yaml = dict(line.split(": ", 1) for line in (tmp_path / "kept.yaml").read_text().splitlines())
    assert yaml["image"] == "kept.pgm" and float(yaml["resolution"]) == pytest.approx(g.resolution)
    origin = [float(v) for v in yaml["origin"].strip("[]").split(",")]
    assert origin[:2] == pytest.approx(list(g.origin))


def test_png_round_trip(tmp_path):
    rng = np.random.default_rng(11)
    image = rng.integers(0, 256, size=(23, 37, 3), dtype=np.uint8)
    hmap.io.write_png(tmp_path / "a.png", image)
    np.testing.assert_array_equal(read_png(tmp_path / "a.png"), image)
    hmap.io.write_png(tmp_path / "b.png", np.asfortranarray(image))  # any layout
    np.testing.assert_array_equal(read_png(tmp_path / "b.png"), image)


def test_bad_input(office, tmp_path):
    mapper, _ = office
    with pytest.raises(ValueError, match=r"image must have shape \(H, W, 3\) with H, W >= 1, got \(4, 4\)"):
        hmap.io.write_png(tmp_path / "x.png", np.zeros((4, 4), dtype=np.uint8))
    with pytest.raises(ValueError, match="image must hold uint8, got dtype float64"):
        hmap.io.write_png(tmp_path / "x.png", np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match="grid must be 'both', 'kept' or 'judged'"):
        hmap.io.write_pgm(mapper.map, tmp_path / "g", grid="mine")
    with pytest.raises(ValueError, match="z_step"):
        hmap.io.write_ply(mapper.map, tmp_path / "p.ply", points=True, z_step=0.0)
    with pytest.raises(ValueError, match="row 0 is not finite"):
        hmap.io.write_points_ply(tmp_path / "p.ply", np.array([[np.nan, 0, 0]]))
    with pytest.raises(hmap.Error, match="no_such_dir"):   # the library's one line, naming the file
        hmap.io.write_ply(mapper.map, tmp_path / "no_such_dir" / "m.ply")
    empty = hmap.HybridMapper(hmap.Params("indoor")).map
    with pytest.raises(hmap.Error, match="empty"):
        hmap.io.write_pgm(empty, tmp_path / "e")
