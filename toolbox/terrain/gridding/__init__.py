"""DEM gridding: nearest, IDW, local polynomial surfaces and TIN-linear, cross-validation,
tiled and distributed (see docs/algorithms/dem.md)."""
