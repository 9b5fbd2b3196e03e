"""I/O helpers shared by every algorithm: vectors (OGR via pyogrio/geopandas), rasters (GDAL via
rasterio), output grids, CRS handling, and atomic output staging."""
