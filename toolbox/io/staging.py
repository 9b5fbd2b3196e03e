"""Atomic outputs: write into a hidden temporary folder beside the final file, rename on success.

A failed or canceled run leaves nothing behind; a successful one replaces each output in one
``os.replace`` (atomic on the same filesystem). The staged file keeps the final file name, so
drivers and layer names that derive from it are unaffected.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path


class OutputStaging:
    """Hands out staged paths for final outputs; :meth:`commit` moves them, :meth:`rollback`
    deletes them."""

    def __init__(self) -> None:
        self._staged: dict[Path, Path] = {}  # final -> staged
        self._folders: list[Path] = []

    def stage(self, final: str | Path) -> Path:
        final = Path(final).expanduser().absolute()
        final.parent.mkdir(parents=True, exist_ok=True)
        folder = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".part",
                                       dir=final.parent))
        self._folders.append(folder)
        staged = folder / final.name
        self._staged[final] = staged
        return staged

    def written(self, final: str | Path) -> bool:
        staged = self._staged.get(Path(final).expanduser().absolute())
        return staged is not None and staged.exists()

    def commit(self) -> list[Path]:
        """Move every staged file that was written and every file beside it in its private
        staging folder (sidecars: ``.aux.xml``, a Shapefile's ``.shx``/``.dbf``/``.prj``, the
        ``<stem>_<layer>`` files of a one-layer-per-file vector format) into place. Returns the
        final paths written."""
        done = []
        for final, staged in self._staged.items():
            if not staged.exists():
                continue
            for item in staged.parent.iterdir():  # the folder holds this output's files only
                target = final.parent / item.name
                if item.is_dir() and target.is_dir():  # a replaced output folder
                    shutil.rmtree(target)
                os.replace(item, target)
            done.append(final)
        self.rollback()
        return done

    def rollback(self) -> None:
        for folder in self._folders:
            shutil.rmtree(folder, ignore_errors=True)
        self._folders.clear()


@contextmanager
def atomic_path(final: str | Path):
    """Context manager yielding a staged path for one file written outside the runner."""
    staging = OutputStaging()
    try:
        yield staging.stage(final)
        staging.commit()
    finally:
        staging.rollback()
