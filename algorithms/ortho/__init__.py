"""Orthophotos: differential rectification of frame photos on a DEM (``ortho:photo``) and of
whole blocks on one shared grid (``ortho:batch``). Library: :mod:`toolbox.ortho`."""
