"""Aerial triangulation: bundle block adjustment, relative orientation (library, no files).

Modules: :mod:`.model` (collinearity with self-calibration, analytic Jacobians), :mod:`.block`
(typed request/result dataclasses), :mod:`.solver` (sparse Gauss-Newton / Levenberg-Marquardt with
the Schur complement on the points), :mod:`.precision` (cofactors, redundancy numbers),
:mod:`.adjust` (robust stage, Baarda data snooping, the whole adjustment),
:mod:`.approximations` (start values: resection and intersection chained over the block),
:mod:`.relative` (relative orientation of a stereo pair), :mod:`.inputs` (tables in),
:mod:`.outputs` (layers out),
:mod:`.synthetic` (blocks with a known truth for tests, demos and benchmarks),
:mod:`.flightplan` (block design: photo scale, strips, photo centres, control layout) and
:mod:`.prediction` (predicted precision of a planned block, tender verdict).
"""
