"""Area topology from restitution linework (thesis S002 §2.2.2, §2.4): ``topology:build_areas``,
``topology:check`` and ``topology:overlay``. The kernels, the input readers and the writers are
the library :mod:`toolbox.topology` (its docstring lists them); the shared parameters and their
translation to typed requests are :mod:`toolbox.ui.topology`.
"""
