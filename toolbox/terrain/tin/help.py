"""Help texts of the TIN parameters, in a module light enough for algorithm specs (no kernels)."""

TIN_HELP = ("TIN: the triangles layer of a tin:delaunay output (the file path is enough: .gpkg, "
            "or .fgb/.parquet/.shp/.geojson with its _nodes file beside it), or any layer of "
            "3D triangles")
