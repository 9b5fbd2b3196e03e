"""IDW: weighted mean of the neighbours' heights, weights 1/d^p (thesis eq. [45])."""

from __future__ import annotations

import math
from typing import Any

from toolbox.terrain.gridding.methods.base import NeighbourMethod
from toolbox.terrain.gridding.request import MethodOptions

IDW_OPTIONS = ("neighbours", "power", "radius", "sectors", "min_neighbours", "max_distance")


def idw_tile(origin, options, tile, arrays):
    """Kernel of one tile (see :func:`toolbox.terrain.gridding.idw_kernel.idw_grid`)."""
    from toolbox.terrain.gridding.idw_kernel import idw_grid

    xs, ys = tile.cell_centres(origin, halo=False)
    return idw_grid(arrays["xyz"], xs, ys, arrays["mask"], **options)


class IdwMethod(NeighbourMethod):
    name = "idw"
    min_points = 1
    default_neighbours = 12
    min_neighbours = 1
    tile_kernel = staticmethod(idw_tile)

    def options(self, request: MethodOptions) -> dict[str, Any]:
        # 1 = no sectors, as SECTORS documents it (the kernels search by sector only above 1)
        return super().options(request) | {"power": float(request.power or 2.0),
                                          "sectors": max(1, int(request.sectors or 1))}

    def halo_neighbours(self, options):
        if options.get("sectors", 0) > 1:  # a sector search may use any point within the radius
            return 0, options.get("radius", math.inf)
        return super().halo_neighbours(options)

    def loo_chunk(self, bins, z, targets, options):
        from toolbox.terrain.gridding.idw_kernel import idw_loo

        return idw_loo(bins, z, targets, **{k: options[k] for k in IDW_OPTIONS
                                            if k in options}), None
