"""Area topology from restitution linework (thesis S002 §2.2.2, §2.4).

Algorithms: ``topology:build_areas`` (clean coded lines, build labelled areas, shared arcs, nodes
and an errors layer), ``topology:check`` (the same checks, errors layer only) and
``topology:overlay`` (intersection, union, difference, symmetric difference of two area layers).

Kernels (shapely geometries in, geometries and counts out; no files): :mod:`.prepare`,
:mod:`.snap`, :mod:`.closure`, :mod:`.noding`, :mod:`.graph`, :mod:`.faces`, :mod:`.labels`,
:mod:`.arcs`, :mod:`.setops`, chained by :func:`.build.build_topology` into the tables of
:mod:`.output`, whose problems are the records of :mod:`.issues`; which codes bound an area is
:mod:`.area_codes`; the tolerances (parameters, else the parameter file, else defaults) are
:mod:`.tolerances`. The inputs are read by :mod:`.inputs` (typed :class:`.inputs.LineworkSources`)
and the GeoPackage layers written by :mod:`.layers`. The parameter file reader is
:mod:`toolbox.io.parameter_file`, shared with the attribution tools.
"""
