"""hmap: height-voxel maps (HMAP), the 2D occupancy grid and ground patches from 3D point clouds.

A thin shell over the C++ libraries (module ``_hmap``)::

    import numpy as np, hmap
    params = hmap.Params("outdoor")
    params.map.cell_size = 0.2            # or params.set("map.cell_size", 0.2)
    mapper = hmap.HybridMapper(params)
    mapper.integrate(points_sensor, T_map_sensor)   # (N, 3) float32/float64, 4x4 pose
    m = mapper.map
    m.occupied(np.array([[1.0, 2.0, 0.5]]))         # -> array([ True])
    m.save("out.hmap")

``hmap.merge_maps`` unites two maps; ``hmap.crop_map`` cuts one to a range of tiles (a map built in
parts, each from the scans that reach its tiles, merges to the one-run map: examples/python/dask_build.py).
Also ``hmap.slam.Slam`` (poses from the scans, scan by scan), ``hmap.eval.trajectory`` (ATE, RPE),
``hmap.io.kitti_sequence``, ``scan_sequence``, ``rgbd_sequence``, ``bag_sequence`` (scans as
(points, pose, stamp), as the CLI reads them), ``hmap.io.read_imu``, ``hmap.sim`` (scenes, sensors,
paths: simulated scans), ``hmap.pvox`` (the PVOX voxel grid), ``hmap.render`` (pictures as NumPy
images) and ``hmap.params_for_scan``
(the parameters ``hmap map`` and ``hmap slam`` choose from the first scan).

Errors of the library (bad parameters, malformed files) raise ``hmap.Error`` (``hmap.InputError``
for a file), both ``ValueError`` subclasses carrying the library's one-line message.
"""

from . import _hmap
from ._hmap import (TILE_CELLS, Error, Grid2D, HybridMapper, InputError, Map, Mapper, Params, align_maps,
                    crop_map, merge_maps, params_for_scan)
from . import eval, io, pvox, render, sim, slam

# Not "eval": `from hmap import *` would hide the builtin eval(); use hmap.eval.
__all__ = ["Error", "InputError", "Params", "params_for_scan", "Mapper", "HybridMapper", "Map", "Grid2D", "merge_maps",
           "align_maps", "crop_map", "TILE_CELLS", "io", "pvox", "render", "sim", "slam"]

_SECTIONS = sorted({name.split(".", 1)[0] for name in Params.names()})


class _Section:
    """The parameters of one section (``params.map``) as attributes, read and set through the
    Params they belong to, so every assignment is validated by the library."""

    __slots__ = ("_params", "_section")

    def __init__(self, params, section):
        object.__setattr__(self, "_params", params)
        object.__setattr__(self, "_section", section)

    def _name(self, attr):
        return f"{self._section}.{attr}"

    def __getattr__(self, attr):
        name = self._name(attr)
        if name not in _NAMES:
            raise AttributeError(f"no parameter {name} (hmap.Params.names() lists them)")
        return self._params.get(name)

    def __setattr__(self, attr, value):
        self._params.set(self._name(attr), value)

    def __dir__(self):
        prefix = self._section + "."
        return [n[len(prefix):] for n in _NAME_LIST if n.startswith(prefix)]

    def __repr__(self):
        return "{" + ", ".join(f"{n}: {getattr(self, n)!r}" for n in self.__dir__()) + "}"


_NAME_LIST = Params.names()  # in the library's order
_NAMES = frozenset(_NAME_LIST)


def _params_getattr(self, section):
    if section in _SECTIONS:
        return _Section(self, section)
    raise AttributeError(f"'Params' has no attribute {section!r} (sections: {', '.join(_SECTIONS)})")


def _params_dir(self):
    return sorted(set(object.__dir__(self)) | set(_SECTIONS))


def _params_repr(self):
    return "hmap.Params(" + ", ".join(f"{n}={self.get(n)!r}" for n in Params.names()) + ")"


Params.__getattr__ = _params_getattr
Params.__dir__ = _params_dir
Params.__repr__ = _params_repr
Params.__copy__ = lambda self: self.copy()
