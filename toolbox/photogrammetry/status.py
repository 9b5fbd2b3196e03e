"""Per-item status codes of a result (0 = ok), shared by the ray intersections of
:mod:`~toolbox.photogrammetry.collinearity` and :mod:`~toolbox.photogrammetry.forward_intersection`."""

from __future__ import annotations

from typing import ClassVar

import numpy as np


class StatusCodes:
    """Mixin of a result holding ``status``, an int array of codes named by ``STATUS``
    (the class's code -> name table; code 0 is ok)."""

    status: np.ndarray
    STATUS: ClassVar[dict[int, str]]

    @property
    def ok(self) -> np.ndarray:
        """True where the item succeeded (status 0)."""
        return self.status == 0

    def status_names(self) -> np.ndarray:
        """The status name of each item (object array, the shape of ``status``)."""
        return np.vectorize(self.STATUS.get, otypes=[object])(self.status)

    def counts(self) -> dict[str, int]:
        """Number of items per status name (only non-zero entries)."""
        values, counts = np.unique(self.status, return_counts=True)
        return {self.STATUS[int(v)]: int(n) for v, n in zip(values, counts, strict=True)}
