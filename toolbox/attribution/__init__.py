"""Code-file driven attribution of restitution entities (thesis S002 §2.2.1-2.2.2, §2.3, §3.6).

- :mod:`.codes`: the code file and the colour file;
- :mod:`.restitution`: readers of the restitution (ASCII export, two-table form, DXF, OGR);
- :mod:`.merge`: the model merge ("fusione");
- :mod:`.apply`: entities + code table -> coded layers and the ``unresolved`` layer;
- :mod:`.editing`: sampling, squaring and alignment kernels.
"""
