"""Readers of the formats the hmap CLI reads, returning numpy arrays, and the writers of
``hmap export`` (PLY, PGM + YAML, OctoMap .bt) taking an ``hmap.Map``, and PNG from an array."""

from ._hmap import io as _io

read_cloud = _io.read_cloud
read_poses = _io.read_poses
open_kitti = _io.open_kitti
write_ply = _io.write_ply
write_points_ply = _io.write_points_ply
floor_under_sensor = _io.floor_under_sensor
write_pgm = _io.write_pgm
write_bt = _io.write_bt
write_png = _io.write_png


open_source = _io.open_source
ScanSequence = _io.ScanSequence
read_imu = _io.read_imu
read_bag_imu = _io.read_bag_imu


def kitti_sequence(dir, max_scans=None, *, poses=None, up=None, rotation=None, with_times=False):
    """The scans of a KITTI-layout folder (``velodyne/*.bin``, with ``poses.txt``, ``calib.txt``
    and ``times.txt`` when present), as ``hmap map --kitti DIR`` and ``hmap slam --kitti DIR``
    read them: an iterator (with ``len()``) of ``(points, T_map_scan, stamp)`` per scan,
    ``points`` an ``(N, 3)`` float32 array in the scanner frame, ``T_map_scan`` a 4x4 pose
    (``poses.txt`` turned into scanner poses by ``calib.txt``'s ``Tr``; ``poses``: another file,
    ``--poses``) or None without poses, ``stamp`` [s] from ``times.txt`` or None.
    ``max_scans``: the first N only (``--scans N``); ``up`` / ``rotation``: ``--up`` /
    ``--rotation`` (an axis such as ``"-y"`` or ``"floor"``; a 3x3 T_map_world);
    ``with_times``: a 4th element, each point's time [s] (float32) or None.

    The folder is listed and its text files checked before the first scan is yielded; each scan
    is read when it is reached. Errors raise ``hmap.InputError`` with the library's message."""
    return _io.open_source(kitti=str(dir), poses=_path(poses), max_scans=max_scans, up=up or "", rotation=rotation,
                           with_times=with_times)


def scan_sequence(files, poses=None, *, max_scans=None, up=None, rotation=None, with_times=False):
    """Scan files in order (.pcd .ply .bin .xyz .txt .csv .pts .vtk), as ``hmap map FILES
    --poses POSES`` reads them: an iterator (with ``len()``) of ``(points, T_map_scan, stamp)``,
    ``T_map_scan`` from ``poses`` (KITTI or TUM, one per scan; None without it), ``stamp`` from a
    TUM pose file or None. Other keywords as kitti_sequence; ``with_times`` gives a PCD's
    per-point times."""
    if isinstance(files, (str, bytes)) or hasattr(files, "__fspath__"):
        files = [files]
    return _io.open_source(files=[str(f) for f in files], poses=_path(poses), max_scans=max_scans, up=up or "",
                           rotation=rotation, with_times=with_times)


def rgbd_sequence(dir, tum="auto", intrinsics=None, depth_scale=None, up=None, max_frames=None, *, rotation=None,
                  with_times=False):
    """The depth images of an RGB-D folder back-projected, as ``hmap map --rgbd DIR`` reads them:
    7-Scenes (``frame-N.depth.png`` + ``.pose.txt``) or TUM (``depth.txt`` + ``groundtruth.txt``),
    told by its files (``tum="auto"`` or False); ``tum=True`` requires TUM (``--tum DIR``). An
    iterator (with ``len()``) of ``(points, T_map_cam, None)``, points in the optical camera
    frame, poses turned so that z is up: ``up`` None finds the floor plane (``--up floor``), or an
    axis of the data's world frame (``"-y"``), or ``rotation`` (3x3). ``intrinsics``: a file of
    fx fy cx cy or a 3x3 matrix; ``depth_scale`` [m per unit]; ``max_frames``: the first N."""
    if tum not in (True, False, "auto"):
        raise ValueError(f"tum must be True, False or 'auto', got {tum!r}")
    where = {"tum": str(dir)} if tum is True else {"rgbd": str(dir)}
    return _io.open_source(**where, intrinsics=_path(intrinsics), depth_scale=depth_scale, up=up or "",
                           rotation=rotation, max_scans=max_frames, with_times=with_times)


def bag_sequence(path, cloud_topic=None, pose_topic=None, tf_frames=None, max_scans=None, *, up=None, rotation=None,
                 with_times=False):
    """The PointCloud2 messages of a recording (ROS 1 bag, MCAP file, rosbag2 folder), as ``hmap
    map --bag PATH`` reads them: an iterator (with ``len()``) of ``(points, T_map_cloud, stamp)``.
    ``cloud_topic``: default the only PointCloud2 topic; poses from ``pose_topic``
    (nav_msgs/Odometry or PoseStamped) or /tf with ``tf_frames`` ``[MAP]`` or ``[MAP, SENSOR]``;
    ``with_times``: a 4th element, each point's time [s] when the cloud has a time field, else
    None. What the reader read past (a recording cut off) comes as a UserWarning. Without ROS
    support in the build: hmap.Error saying so."""
    if isinstance(tf_frames, str):
        tf_frames = [tf_frames]
    return _io.open_source(bag=str(path), cloud_topic=cloud_topic or "", pose_topic=pose_topic or "",
                           tf_frames=list(tf_frames or []), max_scans=max_scans, up=up or "", rotation=rotation,
                           with_times=with_times)


def _path(p):
    return "" if p is None else str(p)


__all__ = ["read_cloud", "read_poses", "open_kitti", "kitti_sequence", "scan_sequence", "rgbd_sequence", "bag_sequence",
           "open_source", "ScanSequence", "read_imu", "read_bag_imu", "write_ply", "write_points_ply", "write_pgm",
           "write_bt", "write_png"]
