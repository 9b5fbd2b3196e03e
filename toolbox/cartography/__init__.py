"""Map deliverables: contours, the map grid, profiles and sections, map sheets, quality report.

Kernels (arrays in, arrays out) live beside small file adapters: :mod:`.contours` and
:mod:`.contour_io`, :mod:`.qml` (contour styles, QML and SLD), :mod:`.compare` (line-by-line agreement).
"""
