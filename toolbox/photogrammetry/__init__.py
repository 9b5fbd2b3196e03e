"""Photogrammetric orientation core: cameras, interior and exterior orientation, collinearity.

Every photo-based algorithm builds on these modules (domain brief ``shared/docs/domain.md``
sections 1-8):

- :mod:`~toolbox.photogrammetry.rotation`: angle units, ``R(omega, phi, kappa)`` exactly as the
  brief's section 3, and the angles back from a matrix;
- :mod:`~toolbox.photogrammetry.camera`: the camera (principal distance, principal point,
  fiducial marks, image size, radial distortion) and image <-> camera coordinates;
- :mod:`~toolbox.photogrammetry.fiducials`: pixel <-> fiducial (image mm) transforms, i.e. the
  interior orientation fitted on the fiducial marks;
- :mod:`~toolbox.photogrammetry.exterior`: exterior orientation (X0, Y0, Z0, omega, phi, kappa,
  angle unit, CRS);
- :mod:`~toolbox.photogrammetry.collinearity`: vectorised (numba) ground -> image and image ->
  ground kernels, monoplotting on a DEM (:mod:`~toolbox.photogrammetry.surface`);
- :mod:`~toolbox.photogrammetry.photo`: one oriented photo chaining all of the above
  (ground <-> pixel);
- :mod:`~toolbox.photogrammetry.project`: the project file tying cameras, photos, orientations
  and the CRS together; :mod:`~toolbox.photogrammetry.readers`: the file formats read.

Algorithms: ``orientation:interior``, ``orientation:intersect``, ``orientation:footprints``,
``orientation:monoplot``, ``orientation:precision``.

Conventions (used throughout)
-----------------------------
- Pixel coordinates are continuous ``(col, row)``: the top-left corner of the image is (0, 0),
  rows grow downward and the centre of pixel ``[i, j]`` is ``(j + 0.5, i + 0.5)`` (GDAL's
  convention). Measured fiducial positions are used as given.
- Image (fiducial) coordinates ``(x, y)`` are millimetres, origin at the fiducial centre, x right,
  y up (brief section 1).
- Ground coordinates ``(X, Y, Z)`` are easting, northing, height in the units of the CRS (metres).
- Angles are stored in radians; every reader and parameter names its unit (rad, deg, gon).
"""
