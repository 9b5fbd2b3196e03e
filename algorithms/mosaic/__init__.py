"""Ortho mosaics: ``mosaic:seamlines`` (cut polygons: Voronoi or least-cost seams),
``mosaic:build`` (the mosaic GeoTIFF: blending, balancing, source index) and ``mosaic:cut``
(clip to map sheets). Kernels live in :mod:`toolbox.mosaic`."""
