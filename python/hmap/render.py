"""Pictures of maps as NumPy images: (H, W, 3) uint8 arrays, row 0 the top (north up), drawn by the
library that draws ``hmap render``'s PNGs (``src/hmap/render``), so the same map gives the same
pixels.

::

    import matplotlib.pyplot as plt, hmap
    m = hmap.Map.load("map.hmap")
    image, vp = hmap.render.grid(m, paths=poses)          # the 2D grid, the path over it
    plt.imshow(image, extent=vp.extent)                   # axes in metres
    hmap.render.top(m)                                    # heights: (image, Viewport)
    hmap.render.oblique(m)                                # image
    hmap.render.pvox(voxel_map, view="iso")               # a hmap.pvox.VoxelMap
    hmap.io.write_png("top.png", image)

``top`` and ``grid`` return the ``Viewport`` the map was drawn in (``extent``, ``origin``,
``m_per_px``, ``pixel(x, y)``); ``draw_path`` draws more poses over such a picture.
"""

from ._hmap import render as _render

Viewport = _render.Viewport
top = _render.top
oblique = _render.oblique
draw_path = _render.draw_path
pvox = _render.pvox


def grid(map, *, max_pixels=2000, paths=None, labels=None, legend=False):
    """The 2D occupancy grid as ``hmap render --layer occupancy`` draws it (free white, occupied
    black, unknown grey; a map without a kept grid, such as a SLAM map, gets the grid ``hmap export
    --pgm`` derives from its columns), with ``paths`` over it (the first blue). Returns
    ``(image, Viewport)``; see ``top``."""
    return _render.top(map, layer="occupancy", max_pixels=max_pixels, paths=paths, labels=labels, legend=legend)


__all__ = ["Viewport", "top", "grid", "oblique", "draw_path", "pvox"]
