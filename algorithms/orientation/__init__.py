"""Orientation algorithms: ``orientation:interior``, ``intersect``, ``footprints``, ``monoplot``,
``precision``, ``check``, ``resection`` and ``absolute``. Their library (cameras, rotations,
collinearity, readers, resection, accuracy rules) and its conventions are described in
:mod:`toolbox.photogrammetry`."""
