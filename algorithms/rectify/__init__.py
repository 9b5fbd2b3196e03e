"""Rectification of photos of a plane (flat terrain, facades) by a plane transform.

Algorithms: ``rectify:estimate`` (transform from control points, with residuals, check points,
gross-error detection and the relief-displacement rule) and ``rectify:image`` (windowed warp to a
GeoTIFF, or a GCP-referenced copy). Libraries: :mod:`toolbox.transforms.control_points`,
:mod:`toolbox.transforms.relief`, :mod:`toolbox.transforms.rectification` (the fit, the
transform document, the photo's footprint and cell size, the GCP copy) and
:mod:`toolbox.transforms.robust` (robust estimation); the warp is the raster engine's
(:func:`toolbox.raster.warp.warp_raster`, the one photo -> ground path of rectify, ortho and
epipolar resampling).
"""
