#!/usr/bin/env python3
"""Cuts the seed corpora of the fuzz targets from the real recordings (small slices: a seed of a
few hundred points exercises every branch a full scan does, and keeps the fuzzer fast).

usage: make_corpus.py DATA_DIR OUT_DIR

Writes OUT_DIR/<target>/<seed> for the targets pcd, ply, xyz, kitti_bin, poses, vtk, depth_png,
intrinsics and rosbag (bags written by tests/ros/make_test_bags.py when python3-rosbag is there).
A missing data set only means fewer seeds: the hand-made ones of fuzz/corpus/ are always there.
The .hmap, PVOX and config seeds are written by the fuzz_seeds program.
"""
import math
import os
import struct
import subprocess
import sys
import tempfile
import zlib

N = 64  # points per cloud seed


def write(out, target, name, data):
    os.makedirs(os.path.join(out, target), exist_ok=True)
    with open(os.path.join(out, target, name), "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


def kitti_points(path, n=N, step=97):
    """n points (x, y, z, intensity) of a KITTI .bin scan, every step-th."""
    with open(path, "rb") as f:
        raw = f.read()
    count = len(raw) // 16
    return [struct.unpack_from("<4f", raw, 16 * (i * step % count)) for i in range(n)]


def lzf_literals(raw):
    """A valid LZF stream of literal runs only (control byte c < 32 copies c + 1 bytes)."""
    out = bytearray()
    for i in range(0, len(raw), 32):
        run = raw[i:i + 32]
        out.append(len(run) - 1)
        out += run
    return bytes(out)


def pcd_seeds(out, pts):
    head = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
            "WIDTH %d\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\n" % (len(pts), len(pts)))
    write(out, "pcd", "ascii.pcd", head + "DATA ascii\n" + "".join("%g %g %g %g\n" % p for p in pts))
    write(out, "pcd", "binary.pcd", head.encode() + b"DATA binary\n" + b"".join(struct.pack("<4f", *p) for p in pts))
    # binary_compressed: fields one after another (x x x ... y y y ...), LZF, sizes in front.
    cols = b"".join(struct.pack("<%df" % len(pts), *[p[k] for p in pts]) for k in range(4))
    comp = lzf_literals(cols)
    write(out, "pcd", "compressed.pcd",
          head.encode() + b"DATA binary_compressed\n" + struct.pack("<II", len(comp), len(cols)) + comp)
    # Organized 8×8 with NaN holes, doubles and an unsigned field, as Kinect clouds have.
    org = ("VERSION .7\nFIELDS x y z rgb\nSIZE 8 8 8 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH 8\nHEIGHT 8\n"
           "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 64\nDATA binary\n").encode()
    body = b"".join(struct.pack("<dddI", *(pts[i % len(pts)][:3] if i % 7 else (math.nan,) * 3), 0x808080)
                    for i in range(64))
    write(out, "pcd", "organized.pcd", org + body)


def ply_seeds(out, pts):
    head = ("ply\nformat %s 1.0\ncomment cut from balm_os0\nelement vertex %d\nproperty float x\nproperty float y\n"
            "property float z\nproperty float intensity\nelement face 1\nproperty list uchar int vertex_indices\n"
            "end_header\n")
    write(out, "ply", "ascii.ply", head % ("ascii", len(pts)) + "".join("%g %g %g %g\n" % p for p in pts) + "3 0 1 2\n")
    for fmt, e in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
        write(out, "ply", fmt + ".ply", (head % (fmt, len(pts))).encode() +
              b"".join(struct.pack(e + "4f", *p) for p in pts) + struct.pack(e + "B3i", 3, 0, 1, 2))
    # Faces first, then vertices of doubles among other properties.
    head2 = ("ply\nformat binary_little_endian 1.0\nelement face 2\nproperty list uchar int vertex_indices\n"
             "element vertex %d\nproperty uchar red\nproperty double x\nproperty double y\nproperty double z\n"
             "end_header\n" % len(pts))
    write(out, "ply", "faces_first.ply", head2.encode() + struct.pack("<B3iB3i", 3, 0, 1, 2, 3, 1, 2, 3) +
          b"".join(struct.pack("<B3d", 7, *p[:3]) for p in pts))


def vtk_seeds(out, data, pts):
    path = os.path.join(data, "sweeping_laser_eth", "cloud.00000.vtk")
    if os.path.exists(path):
        with open(path) as f:
            lines = f.read().splitlines()
        start = next(i for i, l in enumerate(lines) if l.startswith("POINTS"))
        body = lines[start + 1:start + 1 + N]
        write(out, "vtk", "ascii.vtk", "\n".join(lines[:start] + ["POINTS %d float" % len(body)] + body) + "\n")
    head = "# vtk DataFile Version 3.0\ncut from balm_os0\n%s\nDATASET POLYDATA\nPOINTS %d %s\n"
    write(out, "vtk", "binary_float.vtk", (head % ("BINARY", len(pts), "float")).encode() +
          b"".join(struct.pack(">3f", *p[:3]) for p in pts) + b"\nVERTICES 1 2\n1 0\n")
    write(out, "vtk", "binary_double.vtk", (head % ("BINARY", len(pts), "double")).encode() +
          b"".join(struct.pack(">3d", *p[:3]) for p in pts))
    write(out, "vtk", "ascii_grid.vtk", head.replace("POLYDATA", "UNSTRUCTURED_GRID") % ("ASCII", len(pts), "double") +
          "\n".join("%g %g %g" % p[:3] for p in pts) + "\nCELLS 0 0\n")


def png_chunk(kind, body):
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)


def read_gray16_png(path):
    """Rows of a non-interlaced 16-bit grayscale PNG as lists of ints (the 7-Scenes depth maps)."""
    with open(path, "rb") as f:
        raw = f.read()
    pos, idat = 8, b""
    while pos < len(raw):
        (length,) = struct.unpack_from(">I", raw, pos)
        kind = raw[pos + 4:pos + 8]
        body = raw[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            w, h, depth, color, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 16 and color == 0 and interlace == 0
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    data, bpp, stride = zlib.decompress(idat), 2, 2 * w
    rows, prev = [], bytearray(stride)
    for y in range(h):
        f, line = data[y * (stride + 1)], bytearray(data[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - bpp] if x >= bpp else 0
            b = prev[x]
            c = prev[x - bpp] if x >= bpp else 0
            if f == 1:
                line[x] = (line[x] + a) & 0xFF
            elif f == 2:
                line[x] = (line[x] + b) & 0xFF
            elif f == 3:
                line[x] = (line[x] + (a + b) // 2) & 0xFF
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 0xFF
        rows.append(list(struct.unpack(">%dH" % w, bytes(line))))
        prev = line
    return rows


def gray16_png(rows):
    h, w = len(rows), len(rows[0])
    raw = b"".join(b"\0" + struct.pack(">%dH" % w, *r) for r in rows)
    return (b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)) +
            png_chunk(b"IDAT", zlib.compress(raw)) + png_chunk(b"IEND", b""))


def rgbd_seeds(out, data):
    frames = os.path.join(data, "rgbd_7scenes", "rgbd-frames")
    if os.path.isdir(frames):
        rows = read_gray16_png(os.path.join(frames, "frame-000150.depth.png"))
        write(out, "depth_png", "crop16x12.png", gray16_png([r[300:316] for r in rows[230:242]]))
        write(out, "depth_png", "crop_row.png", gray16_png([rows[240][0:64]]))
        with open(os.path.join(frames, "frame-000150.pose.txt"), "rb") as f:
            write(out, "intrinsics", "pose.txt", f.read())
        with open(os.path.join(data, "rgbd_7scenes", "camera-intrinsics.txt"), "rb") as f:
            write(out, "intrinsics", "camera-intrinsics.txt", f.read())
    write(out, "depth_png", "synthetic.png", gray16_png([[(x * 997 + y * 31) % 5000 for x in range(8)] for y in range(8)]))
    write(out, "intrinsics", "four.txt", "525.0, 525.0, 319.5, 239.5\n")


def pose_seeds(out, data):
    path = os.path.join(data, "balm_os0", "poses.txt")
    if not os.path.exists(path):
        return
    with open(path) as f:
        lines = f.read().splitlines()[:8]
    write(out, "poses", "kitti.txt", "\n".join(lines) + "\n")
    tum = []
    for k, line in enumerate(lines):  # the same poses as TUM lines (quaternion from the matrix)
        m = [float(v) for v in line.split()]
        r = [[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]]
        w = math.sqrt(max(0.0, 1 + r[0][0] + r[1][1] + r[2][2])) / 2
        x = math.copysign(math.sqrt(max(0.0, 1 + r[0][0] - r[1][1] - r[2][2])) / 2, r[2][1] - r[1][2])
        y = math.copysign(math.sqrt(max(0.0, 1 - r[0][0] + r[1][1] - r[2][2])) / 2, r[0][2] - r[2][0])
        z = math.copysign(math.sqrt(max(0.0, 1 - r[0][0] - r[1][1] + r[2][2])) / 2, r[1][0] - r[0][1])
        tum.append("%.6f %.9g %.9g %.9g %.9f %.9f %.9f %.9f" % (1e9 + 0.5 * k, m[3], m[7], m[11], x, y, z, w))
    write(out, "poses", "tum.txt", "# timestamp tx ty tz qx qy qz qw\n" + "\n".join(tum) + "\n")


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    data, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    pts = None
    for seq, name in (("balm_os0", "balm"), ("kitti_hdl64_seq16", "kitti")):
        path = os.path.join(data, seq, "velodyne", "000000.bin")
        if os.path.exists(path):
            p = kitti_points(path)
            pts = pts or p
            write(out, "kitti_bin", name + ".bin", b"".join(struct.pack("<4f", *q) for q in p))
            write(out, "xyz", name + ".xyz", "".join("%g %g %g\n" % q[:3] for q in p))
    if pts is None:  # no data: a synthetic ring
        pts = [(5 * math.cos(i / 10), 5 * math.sin(i / 10), 0.1 * i, float(i)) for i in range(N)]
    pcd_seeds(out, pts)
    ply_seeds(out, pts)
    vtk_seeds(out, data, pts)
    csv = os.path.join(data, "sweeping_laser_eth", "car_cloud400.csv")
    if os.path.exists(csv):
        with open(csv) as f:
            write(out, "xyz", "car.csv", "".join(f.readlines()[:N + 1]))
    write(out, "xyz", "named.csv", "//X;Y;Z;Intensity\n" + "".join("%g;%g;%g;%g\n" % q for q in pts[:16]))
    pose_seeds(out, data)
    rgbd_seeds(out, data)
    # ROS bags from the first two real scans, every 2000th point (ROS's own writer).
    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "ros", "make_test_bags.py")
    with tempfile.TemporaryDirectory() as tmp:
        ok = subprocess.run(["/usr/bin/python3", script, data, tmp, "2", "2000"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode == 0
        if ok:
            for name in sorted(os.listdir(tmp)):
                if not name.endswith(".bag"):
                    continue
                with open(os.path.join(tmp, name), "rb") as f:
                    data = f.read()
                write(out, "rosbag", name, data)
                # Bags cut off (a recorder killed before its index): read linearly up to the cut.
                if name.startswith("chunked"):
                    for k in (1, 2):
                        write(out, "rosbag", f"cut_{k}of3_{name}", data[:len(data) * k // 3])
        else:
            print("make_corpus.py: no ROS bag seeds (python3-rosbag missing or balm_os0 absent)")
    print("make_corpus.py: seeds written to", out)


if __name__ == "__main__":
    main()
