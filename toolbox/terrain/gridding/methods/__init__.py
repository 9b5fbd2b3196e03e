"""The gridding methods, one module each (thesis S002 par. 2.5.2): ``nearest``, ``idw``,
``plane`` / ``quadratic`` / ``cubic`` (local polynomials) and ``tin_linear``.

A method (:class:`~toolbox.terrain.gridding.methods.base.Method`) knows its options, how to plan
the tiles of a run (which arrays each tile needs, which kernel computes it) and how to predict
its data points left out one at a time; ``dem:<method>`` and ``dem:cross_validate`` take
everything method-specific from here, so a method grids and cross-validates with the same code
and the same options. Kernels are imported when a run starts, not with this package.
"""

from __future__ import annotations

from toolbox.terrain.gridding.methods.base import Method
from toolbox.terrain.gridding.methods.idw import IdwMethod
from toolbox.terrain.gridding.methods.nearest import NearestMethod
from toolbox.terrain.gridding.methods.polynomial import PolynomialMethod
from toolbox.terrain.gridding.methods.tin_linear import TinLinearMethod

METHODS: dict[str, Method] = {m.name: m for m in (
    NearestMethod(), IdwMethod(), PolynomialMethod("plane", 1, 8),
    PolynomialMethod("quadratic", 2, 12), PolynomialMethod("cubic", 3, 20), TinLinearMethod())}

__all__ = ["METHODS", "Method"]
