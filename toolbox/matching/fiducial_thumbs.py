"""Thumbnails of fiducial marks for visual checking: the scan around each mark, stretched to 8
bits and enlarged, with the found centre drawn (green cross) or, for a missing mark, its
predicted position (red square) and status."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toolbox.matching.fiducial_search import PhotoMarks, ScanReader


def write_thumbnails(folder: Path, reader: ScanReader, found: PhotoMarks, half_px: int,
                     size: int = 192) -> list[Path]:
    """One PNG per mark, ``<photo>_<mark>.png``, of the scan ``2·half_px`` pixels around it."""
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for r in found.marks:
        centre = (r.col_px, r.row_px) if r.ok else r.predicted
        c, w = int(np.floor(centre[0])), int(np.floor(centre[1]))
        window, (c0, r0) = reader.window(c - half_px, w - half_px, c + half_px + 1,
                                         w + half_px + 1)
        canvas = np.zeros((2 * half_px + 1, 2 * half_px + 1), np.float32)
        if window.size:
            canvas[r0 - (w - half_px):r0 - (w - half_px) + window.shape[0],
                   c0 - (c - half_px):c0 - (c - half_px) + window.shape[1]] = window
        lo, hi = np.percentile(canvas, (1, 99)) if canvas.size else (0, 1)
        grey = np.clip((canvas - lo) * 255.0 / max(hi - lo, 1e-6), 0, 255).astype(np.uint8)
        scale = size / grey.shape[0]
        big = cv2.resize(grey, (size, size), interpolation=cv2.INTER_NEAREST)
        image = cv2.cvtColor(big, cv2.COLOR_GRAY2BGR)
        x = (centre[0] - (c - half_px)) * scale
        y = (centre[1] - (w - half_px)) * scale
        if r.ok:
            colour = (0, 200, 0)
            cv2.line(image, (int(x) - 12, int(y)), (int(x) + 12, int(y)), colour, 1)
            cv2.line(image, (int(x), int(y) - 12), (int(x), int(y) + 12), colour, 1)
            label = f"{r.mark} {r.score:.2f}"
        else:
            colour = (0, 0, 230)
            cv2.rectangle(image, (int(x) - 10, int(y) - 10), (int(x) + 10, int(y) + 10), colour, 1)
            label = f"{r.mark} {r.status}"
        cv2.putText(image, label, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1)
        path = folder / f"{found.photo}_{r.mark}.png"
        cv2.imwrite(str(path), image)
        written.append(path)
    return written
