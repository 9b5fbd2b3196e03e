"""Code-file driven attribution (thesis S002 §2.2-2.3, §3.6): ``attribution:apply``,
``attribution:merge``, ``attribution:sample``, ``attribution:square``, ``attribution:align``.
Library code in :mod:`toolbox.attribution` and :mod:`toolbox.styles`."""
