"""Readers of the formats the hmap CLI reads, returning numpy arrays, and the writers of
``hmap export`` (PLY, PGM + YAML, OctoMap .bt) taking an ``hmap.Map``, and PNG from an array."""

from ._hmap import io as _io

read_cloud = _io.read_cloud
read_poses = _io.read_poses
open_kitti = _io.open_kitti
write_ply = _io.write_ply
write_points_ply = _io.write_points_ply
write_pgm = _io.write_pgm
write_bt = _io.write_bt
write_png = _io.write_png


def kitti_sequence(dir, max_scans=None):
    """The scans of a KITTI-layout folder (``velodyne/*.bin``, with ``poses.txt``, ``calib.txt``
    and ``times.txt`` when present), as ``hmap map --kitti DIR`` and ``hmap slam --kitti DIR``
    read them: yields ``(points, T_map_scan, stamp)`` per scan, ``points`` an ``(N, 3)`` float32
    array in the scanner frame, ``T_map_scan`` a 4x4 pose (``poses.txt`` turned into scanner
    poses by ``calib.txt``'s ``Tr``) or None without ``poses.txt``, ``stamp`` [s] from
    ``times.txt`` or None. ``max_scans``: the first N only (``--scans N``).

    The folder is listed and its text files checked before the first scan is yielded; each scan
    is read when it is reached. Errors raise ``hmap.InputError`` with the library's message."""
    seq = _io.open_kitti(dir, max_scans)
    poses, times = seq["T_map_scan"], seq["times"]
    for k, path in enumerate(seq["scans"]):
        yield (read_cloud(path),
               None if poses is None else poses[k],
               None if times is None else float(times[k]))


__all__ = ["read_cloud", "read_poses", "open_kitti", "kitti_sequence", "write_ply", "write_points_ply", "write_pgm",
           "write_bt", "write_png"]
