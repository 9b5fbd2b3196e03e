"""Constants of the ortho kernels, in a module without numba, so that the paths that do not
compile (:mod:`toolbox.ortho.grid_numpy`) can name them without numba's start-up."""

DEFAULT_BLOCK = 64  # coarse-grid step of the distortion, cells: the thesis' 64, fastest measured
DEFAULT_TOLERANCE_PX = 0.05  # largest interpolation error accepted, photo pixels
#: block modes written by the kernel
BLOCK_PROJECTIVE, BLOCK_INTERPOLATED, BLOCK_EXACT = 0, 1, 2
#: fields of the ``stats`` array of :func:`toolbox.ortho.kernels.ortho_window_projective`
(STAT_COL_MIN, STAT_ROW_MIN, STAT_COL_MAX, STAT_ROW_MAX, STAT_MISSING, STAT_OUTSIDE_DEM,
 STAT_OUTSIDE_PHOTO, STAT_MAX_RELIEF) = range(8)
RELIEF_ROWS = 8  # every 8th row (all its columns) enters the largest relief displacement
