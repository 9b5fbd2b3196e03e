"""Control-point measurement templates: where each ground control point should appear on every
oriented photo (collinearity through the approximate orientation), with an image chip around
the prediction for the operator to confirm or move."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolbox.matching.images import ImageSource


@dataclass
class Prediction:
    point_id: str
    photo: str
    col_px: float
    row_px: float
    xyz: np.ndarray
    chip: Path | None = None


def predict(photo, source: ImageSource, ids: list[str], xyz: np.ndarray, margin_px: float
            ) -> list[Prediction]:
    """Control points that fall on ``photo`` at least ``margin_px`` inside its borders."""
    uv = photo.ground_to_pixel(xyz, behind="nan")
    inside = (np.isfinite(uv).all(axis=1) & (uv[:, 0] >= margin_px)
              & (uv[:, 0] <= source.width - margin_px) & (uv[:, 1] >= margin_px)
              & (uv[:, 1] <= source.height - margin_px))
    return [Prediction(ids[k], photo.id, float(uv[k, 0]), float(uv[k, 1]), xyz[k])
            for k in np.flatnonzero(inside)]


def write_chip(path: Path, source: ImageSource, p: Prediction, half: int, size: int = 256
               ) -> Path:
    """PNG of the photo ``2·half`` pixels around the prediction, enlarged to ``size``, with the
    predicted position as a red cross."""
    import cv2

    c0 = int(np.floor(p.col_px)) - half
    r0 = int(np.floor(p.row_px)) - half
    grey = source.window(c0, r0, 2 * half + 1, 2 * half + 1)
    scale = size / grey.shape[0]
    image = cv2.cvtColor(cv2.resize(grey, (size, size), interpolation=cv2.INTER_NEAREST),
                         cv2.COLOR_GRAY2BGR)
    x, y = int((p.col_px - c0) * scale), int((p.row_px - r0) * scale)
    cv2.line(image, (x - 14, y), (x + 14, y), (0, 0, 230), 1)
    cv2.line(image, (x, y - 14), (x, y + 14), (0, 0, 230), 1)
    cv2.putText(image, f"{p.point_id} on {p.photo}", (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                (0, 0, 230), 1)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), image)
    return path
