"""Rectification of photos of a plane (flat terrain, facades) by a plane transform.

Algorithms: ``rectify:estimate`` (transform from control points, with residuals, check points,
gross-error detection and the relief-displacement rule) and ``rectify:image`` (windowed warp to a
GeoTIFF, or a GCP-referenced copy). Kernels: :mod:`.control_points`, :mod:`.relief`,
:mod:`.warp` (the output-window -> source-coordinates -> ``cv2.remap`` machinery, reusable by
orthorectification); robust estimation lives in :mod:`toolbox.transforms.robust`.
"""
