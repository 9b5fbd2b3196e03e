"""Orthophoto mosaics (thesis S002 §3.8, "linee di taglio"; ../shared/docs/domain.md §15).

- :mod:`.sources`: the orthos as mosaic sources (valid-data footprints, nadir points, windowed
  reads onto the mosaic grid);
- :mod:`.partition`: the Voronoi ("LPV") partition of the mosaic area into cut polygons;
- :mod:`.seams`: least-cost ("PPD") seams in the overlaps; :mod:`.route` the least-cost path
  (compiled A*, coarse-to-fine), :mod:`.kernels` the compiled terms of their cost surface;
- :mod:`.blend`: feathering weights and multi-band (Laplacian pyramid) blending;
- :mod:`.balance`: block-wide gain/offset radiometric balancing;
- :mod:`.build`: the windowed mosaic writer (one kernel per output window);
- :mod:`.sheets`: map-sheet grids and clipping ("taglio" to the map unit).

Conventions: arrays are ``(bands, rows, cols)`` float32 with a separate boolean ``valid`` mask
``(rows, cols)``; row 0 is north; ground coordinates are x east, y north in the mosaic CRS.
"""
