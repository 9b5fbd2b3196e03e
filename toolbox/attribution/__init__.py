"""Code-file driven attribution of restitution entities (thesis S002 §2.2.1-2.2.2, §2.3, §3.6).

- the code file and the colour file: :mod:`toolbox.io.code_file` (shared with the styles);
- :mod:`.restitution`: readers of the restitution (ASCII export, two-table form, DXF, OGR);
  :mod:`.sources`: the restitution inputs as the ``attribution:*`` algorithms read them;
- :mod:`.model_merge`: the model merge ("fusione");
- :mod:`.coding`: entities + code table -> coded layers and the ``unresolved`` layer;
  :mod:`.output`: those layers written with their styles;
- :mod:`.editing`: sampling, squaring and alignment kernels; :mod:`.edit_io`: their I/O.
"""
