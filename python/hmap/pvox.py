"""The PVOX probabilistic voxel grid (``hmap pvox``): a sparse grid of cubic voxels counting hits
and misses, and its builder that sets the voxel edge from a Kalman-filtered position.

::

    import numpy as np, hmap
    grid = hmap.pvox.VoxelMap(0.05)                       # edge [m]
    grid.insert(points_sensor, T_map_sensor)              # (N, 3), 4x4
    grid.probability(np.array([[1.0, 2.0, 0.5]]))         # p of the voxels holding the points
    grid.save("map.pvox")                                 # what `hmap info` and `hmap render` read

    mapper = hmap.pvox.Mapper()                           # `hmap pvox`'s defaults
    mapper.add_scan(points_sensor, T_previous_current, measured_xy=None)   # None: align to the map
    mapper.map.save("map.pvox")
"""

from ._hmap import pvox as _pvox

VoxelMap = _pvox.VoxelMap
Mapper = _pvox.Mapper

__all__ = ["VoxelMap", "Mapper"]
