"""Built-in algorithms, one folder per domain, one module per algorithm.

Every module here is imported by :func:`toolbox.registry.discover`; an algorithm class decorated
with :func:`toolbox.registry.register` becomes available as ``toolbox run group:name``.
"""
