"""Input features as messages name them: 1-based rows, the order of QGIS' attribute table."""

from __future__ import annotations

import numpy as np


def rows_text(mask, limit: int = 10) -> str:
    """The 1-based rows where ``mask`` is true, ``2, 5, 9``: the first ``limit``, then how
    many more."""
    rows = (np.flatnonzero(mask) + 1).tolist()
    more = f" and {len(rows) - limit} more" if len(rows) > limit else ""
    return ", ".join(map(str, rows[:limit])) + more
