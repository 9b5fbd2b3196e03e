"""Orthorectification: one photo (or a block) onto a map grid through a DEM, window by window.

One path from a camera to a raster::

    plan = plan.plan_photo(photo, dem, crs)            # checks, footprint, mean height, GSD, grid
    report = run.orthorectify(photo, image, dem, plan.grid, output, run.OrthoOptions(...))

:func:`~toolbox.ortho.run.orthorectify` hands :class:`~toolbox.ortho.windows.OrthoWindows` (a
coordinate map declaring the planned and measured capabilities of :mod:`toolbox.raster.maps`) to
:func:`toolbox.raster.warp.warp_to_geotiff`; per output window it takes the DEM under the window
(:class:`~toolbox.ortho.dem.DemSampler`), maps it through the camera and resamples the photo.

Modules, one concern each:

- :mod:`.sensor`: the film camera as arrays and its compiled map (:class:`CollinearityMap`);
  other cameras map through their own ``project`` (:mod:`toolbox.cameras`);
- :mod:`.kernels`: the one-pass window kernel (heights, map, counts) and the plain map;
- :mod:`.distortion`: the radial distortion added by blocks, blended within a proven bound;
- :mod:`.heights`: bilinear DEM heights on a grid or at points; :mod:`.dem`: the DEM source;
- :mod:`.visibility`: hidden cells (true ortho); :mod:`.metrics`: the report's measures;
- :mod:`.plan`: checks, footprint and output grid; :mod:`.windows`: the per-window map;
- :mod:`.run`: one photo to a GeoTIFF; :mod:`.block`: a block's picklable per-photo task.
"""
