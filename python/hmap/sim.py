"""The simulator (``hmap simulate``'s parts): built-in scenes, sensors, scripted paths, noisy
odometry and the KITTI-layout sequence writer.

::

    import hmap
    scene = hmap.sim.Scene("parking")
    path = hmap.sim.car_path(hmap.sim.route("parking"))        # what `hmap simulate --scene parking` drives
    lidar = hmap.sim.Sensor("vlp16", seed=1)
    scan = lidar.scan(scene, path.poses[0], path.times[0])    # scan["points"]: (N, 3) float32, sensor frame

The same seed and the same calls give the same points as ``hmap simulate --seed``: the first
frames of ``hmap simulate --scene parking --sensor vlp16`` are ``lidar.scan`` at ``path.poses[k]``.
``hmap.sim.simulate("parking", "vlp16", frames=20, seed=1)`` is the whole of ``hmap simulate``
(the same library call: scans, true poses, noisy odometry, truth clouds, IMU) in memory, and
``write_sequence`` writes its KITTI folder.
"""

from ._hmap import sim as _sim

Scene = _sim.Scene
Sensor = _sim.Sensor
Trajectory = _sim.Trajectory
scene_names = _sim.scene_names
kind_names = _sim.kind_names
route = _sim.route
car_path = _sim.car_path
diff_drive_path = _sim.diff_drive_path
noisy_odometry = _sim.noisy_odometry
write_sequence = _sim.write_sequence
simulate = _sim.simulate

__all__ = ["Scene", "Sensor", "Trajectory", "scene_names", "kind_names", "route", "car_path", "diff_drive_path", "noisy_odometry",
           "write_sequence", "simulate"]
