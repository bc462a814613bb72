"""SLAM on the HMAP (section IV-C): ``hmap slam`` scan by scan.

::

    import hmap
    scans = hmap.io.kitti_sequence("../shared/data/kitti_hdl64_seq16", max_scans=5)
    first, _, _ = next(scans)
    slam = hmap.slam.Slam(hmap.params_for_scan(first)["params"])   # as `hmap slam` chooses them
    slam.process(first)
    for points, _, stamp in scans:
        step = slam.process(points, stamp)      # step["T_map_sensor"], step["converged"], ...
    slam.poses                                  # (5, 4, 4), what `hmap slam --out O` writes to O/poses.txt

With an IMU, as ``hmap slam --imu FILE``: ``Slam(params, imu=hmap.io.read_imu(FILE))`` (or a dict
of ``stamps`` (N,), ``gyro`` (N, 3), ``accel`` (N, 3) arrays); every scan then needs its stamp.
"""

from ._hmap import slam as _slam

Slam = _slam.Slam

__all__ = ["Slam"]
