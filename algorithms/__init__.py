"""Built-in algorithms, one folder per domain, one module per algorithm.

The module ``algorithms/<group>/<name>.py`` holds the algorithm of id ``group:name``, a class
decorated with :func:`toolbox.registry.register`. The registry finds it by its path
(:func:`toolbox.registry.builtin_modules`) and imports it when the id is run, asked for help or
listed: there is no other list to edit. Shared parameter presets and the translation of
parameters to the libraries' typed requests live in :mod:`toolbox.ui`.
"""
