"""One base for the counters summed over windows, tiles or triangles (ortho windows, warp runs,
cut/fill): a dataclass whose number fields add, whose ``MAXIMA`` fields keep the largest value
and whose dict fields add key by key."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any, ClassVar


@dataclass
class Counters:
    """Subclass as a ``@dataclass`` with number (or dict of number) fields."""

    MAXIMA: ClassVar[tuple[str, ...]] = ()

    def add(self, other: Counters) -> None:
        """Accumulate ``other`` (same class) into this one."""
        for f in fields(self):
            mine, theirs = getattr(self, f.name), getattr(other, f.name)
            if isinstance(mine, dict):
                for key, value in theirs.items():
                    mine[key] = mine.get(key, 0) + value
            elif f.name in self.MAXIMA:
                setattr(self, f.name, max(mine, theirs))
            else:
                setattr(self, f.name, mine + theirs)

    def __iadd__(self, other: Counters) -> Counters:
        self.add(other)
        return self

    def as_dict(self) -> dict[str, Any]:
        """The fields by name (dicts copied)."""
        return asdict(self)
