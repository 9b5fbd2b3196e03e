"""Tie points across a block of photos: the whole pipeline, from image files to tracks.

1. each photo is read at a reduced level (longer side <= ``max_size``, area average: bounded
   memory for 16644 x 16644 scans) and its features are detected tile by tile
   (:mod:`features`), outside a border of ``border_px`` (fiducial marks, data strip);
2. pairs (:mod:`pairs`): footprint overlap when the photos are oriented and a terrain height is
   known; else, with approximate positions (a GNSS log, the orientations' centres, EXIF GPS),
   each photo's nearest neighbours; otherwise every pair is matched on thumbnails first and
   kept when it verifies;
3. each pair: ratio test, USAC/MAGSAC fundamental matrix, and with orientations the epipolar
   distance (:mod:`matching`);
4. tracks by union-find, inconsistent ones dropped (:mod:`tracks`);
5. thinning per model (:mod:`thinning`), then sub-pixel NCC refinement of the kept tracks on
   full-resolution patches (:mod:`refine`): an observation that does not refine is dropped.

Coordinates are full-resolution pixels (col, row; top-left pixel centre at (0.5, 0.5)).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.feedback import current_runs, working_for
from toolbox.matching import matching, pairs, refine, thinning, tracks
from toolbox.matching.features import Features, border_mask, detect
from toolbox.matching.images import ImageSource


@dataclass
class TiePointOptions:
    """Settings of :func:`tie_points` (pixels are full-resolution unless said otherwise)."""

    detector: str = "sift"
    max_size: int = 3000  # longer side of the level the features are detected on, px
    tile: int = 1024  # detection tile on that level, px
    per_tile: int = 2500  # features per tile, at most
    max_features: int = 10000  # per photo: more tiles share it (a big level: fewer per tile)
    workers: int = 0  # threads for detection and matching (0: one per core)
    ratio: float = 0.8  # Lowe's ratio test
    f_threshold: float = 1.0  # MAGSAC inlier threshold, px of the detection level
    min_matches: int = 15  # fewer verified matches: the pair is not tied
    border_px: float = 0.0  # masked border (fiducials, data strip)
    target_per_model: int = 64  # Gruber cells per model
    refine: bool = True
    half: int = 10  # NCC template half size
    min_ncc: float = 0.75
    epipolar_tolerance: float | None = None  # px; with orientations, drop matches farther
    min_overlap: float = 5.0  # percent, footprint pairs
    terrain_height: float | None = None  # plane for the footprints
    thumbnail_size: int = 800
    pair_selection: str = "auto"  # auto | footprints | neighbours | thumbnails
    neighbours: int = 8  # neighbours mode: nearest photos per photo (plus Delaunay edges)
    positions: np.ndarray | None = None  # (N, 2) planar photo positions (a GNSS log), or None
    executor: Any = None  # where photos are detected and pairs matched (toolbox.executor.
    # Executor); None: threads


@dataclass
class BlockPhoto:
    """A photo to match: its id, the image and, when known, the oriented Photo. ``level``
    holds the detection level between the thumbnail pass and detection (read once)."""

    id: str
    source: ImageSource
    photo: Any = None
    level: tuple[int, tuple[np.ndarray, tuple[float, float]]] | None = field(default=None,
                                                                            repr=False)


#: detection levels kept between the thumbnail pass and detection, at most (bytes, all photos)
LEVEL_CACHE_BYTES = 512_000_000


@dataclass
class PairReport:
    a: str
    b: str
    overlap_percent: float | None
    candidates: int = 0
    verified: int = 0
    kept: int = 0
    cells_3x3: int = 0
    median_f_residual_px: float | None = None
    median_epipolar_px: float | None = None
    status: str = "ok"


@dataclass
class Track:
    """One tie point: photo indices, full-resolution positions, a priori sigma (px) each."""

    photos: list[int]
    xy: np.ndarray
    sigma: np.ndarray
    refined: bool


@dataclass
class TiePointResult:
    photos: list[BlockPhoto]
    tracks: list[Track]
    pairs: list[PairReport]
    untied: list[str]  # photos in no verified pair
    dropped_inconsistent: int
    features: dict[str, int] = field(default_factory=dict)
    pair_selection: str = ""


Progress = Callable[[float, str], None]


def _median(values: np.ndarray) -> float | None:
    values = values[np.isfinite(values)]
    return float(np.median(values)) if len(values) else None


def _level(bp: BlockPhoto, max_size: int, keep: bool = False
           ) -> tuple[np.ndarray, tuple[float, float]]:
    """The photo decimated to ``max_size`` (grey uint8) and its factors; read once when
    ``keep`` (held in ``bp.level`` until :func:`_features` at that size takes it)."""
    if bp.level is not None and bp.level[0] == max_size:
        level = bp.level[1]
        if not keep:
            bp.level = None
        return level
    level = bp.source.level(bp.source.scale_for(max_size))
    if keep:
        bp.level = (max_size, level)
    return level


def _thumbnail(bp: BlockPhoto, opts: TiePointOptions, keep: bool
               ) -> tuple[np.ndarray, tuple[float, float]]:
    """The thumbnail (``thumbnail_size``), from the detection level when it is kept (one read
    of the file instead of two: a big scan's decimated read costs seconds)."""
    import cv2

    if not keep or bp.source.scale_for(opts.thumbnail_size) <= 1.0:
        return bp.source.level(bp.source.scale_for(opts.thumbnail_size))
    image, _ = _level(bp, opts.max_size, keep=True)
    scale = bp.source.scale_for(opts.thumbnail_size)
    w = max(1, int(round(bp.source.width / scale)))
    h = max(1, int(round(bp.source.height / scale)))
    small = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA)
    return small, (bp.source.width / w, bp.source.height / h)


def _features(bp: BlockPhoto, opts: TiePointOptions, max_size: int,
              level: tuple[np.ndarray, tuple[float, float]] | None = None
              ) -> tuple[Features, float]:
    image, (sx, sy) = level if level is not None else _level(bp, max_size)
    mask = border_mask(*image.shape, opts.border_px / min(sx, sy))
    tiles = int(np.ceil(image.shape[0] / opts.tile) * np.ceil(image.shape[1] / opts.tile))
    per_tile = max(1, min(opts.per_tile, opts.max_features // tiles))
    feats = detect(image, mask, opts.detector, opts.tile, per_tile)
    return feats.scaled(sx, sy), float(np.sqrt(sx * sy))


def _where(opts: TiePointOptions) -> tuple[Any, TiePointOptions]:
    """Where the tasks of ``opts`` run (its executor, else local threads) and the options the
    tasks carry: without the executor (workers need none)."""
    from toolbox.executor import resolve_executor

    executor = opts.executor or resolve_executor("local", opts.workers or None)
    return executor, replace(opts, executor=None)


@dataclass(frozen=True)
class DetectTask:
    """One photo whose features to detect (picklable for a Dask worker, which reads the image
    by its path): at ``opts.max_size``, or on its thumbnail (:func:`_thumbnail`, from the
    detection level when ``keep``)."""

    photo: BlockPhoto
    opts: TiePointOptions
    thumbnail: bool = False
    keep: bool = False


def detect_photo(task: DetectTask) -> tuple[Features, float, tuple[float, float] | None]:
    """:func:`_features` of one photo, with the grey stretch its reading set (a worker's
    copy of the image sends it back, so the client reads later windows the same way)."""
    if task.thumbnail:
        level = _thumbnail(task.photo, task.opts, task.keep)
        features, scale = _features(task.photo, task.opts, task.opts.thumbnail_size, level)
    else:
        features, scale = _features(task.photo, task.opts, task.opts.max_size)
    return features, scale, task.photo.source.stretch


def detect_photos(photos: list[BlockPhoto], used: list[int], opts: TiePointOptions,
                  thumbnail: bool = False, keep: bool = False
                  ) -> Iterator[tuple[int, Features, float]]:
    """``(k, features, level scale)`` of every photo ``k`` in ``used``, in that order
    (:class:`DetectTask`), detected through :func:`toolbox.executor.map_tiles`: local threads
    (OpenCV releases the GIL; a photo's level kept from the thumbnail pass is used) or the
    Dask cluster of ``opts.executor`` (the workers read the photos)."""
    from toolbox.executor import map_tiles

    executor, bare = _where(opts)
    remote = executor.kind == "dask"
    tasks = [DetectTask(BlockPhoto(photos[k].id, photos[k].source) if remote else photos[k],
                        bare, thumbnail, keep) for k in used]
    for k, (features, scale, stretch) in zip(used, map_tiles(detect_photo, tasks,
                                                             executor=executor), strict=True):
        if remote and photos[k].source.stretch is None:
            photos[k].source.stretch = stretch
        yield k, features, scale


def _match(fa: Features, fb: Features, opts: TiePointOptions, level_scale: float,
           pa: Any = None, pb: Any = None) -> matching.PairMatches:
    """Match two photos' features; ``pa``, ``pb``: their oriented photos (or None)."""
    ia, ib = matching.ratio_matches(fa, fb, opts.ratio, opts.detector)
    cameras = None
    if matching.has_camera(pa) and matching.has_camera(pb):
        angle = 0.5 * (matching.pixel_angle(pa) + matching.pixel_angle(pb))
        cameras = (matching.normaliser(pa), matching.normaliser(pb), angle)
    return matching.verify(fa, fb, ia, ib, opts.f_threshold * level_scale,
                           min_matches=opts.min_matches, cameras=cameras)


@dataclass(frozen=True)
class PairTask:
    """One pair to match, picklable for a Dask worker: both photos' features (keypoints and
    descriptors, never the images), the options, the detection-level scale and the two
    photos' orientations (cameras turn pixels into rays), or None."""

    fa: Features
    fb: Features
    opts: TiePointOptions
    level_scale: float
    pa: Any = None
    pb: Any = None


def match_pair(task: PairTask) -> matching.PairMatches:
    """Match one pair (module level: a Dask worker imports it by name). The model comes back
    without its normalisers (functions of the cameras, not picklable): :func:`match_pairs`
    puts them back on the client."""
    m = _match(task.fa, task.fb, task.opts, task.level_scale, task.pa, task.pb)
    if m.model is not None:
        m.model.to_a = m.model.to_b = None
    return m


def match_pairs(tasks: list[PairTask], opts: TiePointOptions) -> list[matching.PairMatches]:
    """:func:`match_pair` on every task through :func:`toolbox.executor.map_tiles` (local
    threads, or the Dask cluster of ``opts.executor``), results in task order."""
    from toolbox.executor import map_tiles

    executor, bare = _where(opts)
    found = list(map_tiles(match_pair, [PairTask(t.fa, t.fb, bare, t.level_scale, t.pa, t.pb)
                                        for t in tasks], executor=executor))
    for t, m in zip(tasks, found, strict=True):
        if m.model is not None and m.model.kind == "E":
            m.model.to_a, m.model.to_b = matching.normaliser(t.pa), matching.normaliser(t.pb)
    return found


def photo_positions(photos: list[BlockPhoto], opts: TiePointOptions
                    ) -> tuple[np.ndarray, str] | None:
    """Planar positions of every photo and where they come from (the GNSS log of ``opts``,
    the orientations' centres, the images' EXIF GPS), or None when not every photo has one."""
    from toolbox.matching.positions import lonlat_to_local

    if opts.positions is not None:
        return np.asarray(opts.positions, dtype="float64"), "positions"
    if all(bp.photo is not None and bp.photo.exterior is not None for bp in photos):
        return np.array([bp.photo.exterior.centre[:2] for bp in photos]), "orientations"
    if all(bp.source.lonlat is not None for bp in photos):
        lonlat = np.array([bp.source.lonlat for bp in photos])
        return lonlat_to_local(lonlat[:, 0], lonlat[:, 1]), "EXIF GPS"
    return None


def select_pairs(photos: list[BlockPhoto], opts: TiePointOptions
                 ) -> tuple[list[tuple[int, int, float | None]], str]:
    """Candidate pairs and how they were chosen (``opts.pair_selection``; "auto": footprints
    when oriented with a terrain height, else neighbours when positions are known, else
    thumbnails)."""
    how = opts.pair_selection
    oriented = all(bp.photo is not None and bp.photo.exterior is not None for bp in photos)
    if how in ("auto", "footprints") and oriented and opts.terrain_height is not None:
        return pairs.footprint_pairs([bp.photo for bp in photos], opts.terrain_height,
                                     opts.min_overlap), "footprints"
    if how == "footprints":
        raise InputDataError("PAIR_SELECTION footprints needs every photo oriented (PROJECT "
                             "with exterior orientations) and TERRAIN_HEIGHT")
    known = photo_positions(photos, opts) if how in ("auto", "neighbours") else None
    if known is not None:
        xy, source = known
        return pairs.neighbour_pairs(xy, opts.neighbours), f"neighbours ({source})"
    if how == "neighbours":
        raise InputDataError("PAIR_SELECTION neighbours needs a position for every photo: "
                             "POSITIONS (a GNSS log), orientations in PROJECT or EXIF GPS tags "
                             "in every image")
    return _thumbnail_pairs(photos, opts), "thumbnails"


def _thumbnail_pairs(photos: list[BlockPhoto], opts: TiePointOptions
                     ) -> list[tuple[int, int, float | None]]:
    """Every pair matched on thumbnails; those that verify."""
    small = TiePointOptions(**{**opts.__dict__, "per_tile": 1000})
    every = pairs.all_pairs(len(photos))
    # every photo will be detected at max_size: keep that level from this pass when it fits
    sizes = [bp.source.width * bp.source.height / bp.source.scale_for(opts.max_size) ** 2
             for bp in photos]
    keep = sum(sizes) <= LEVEL_CACHE_BYTES
    thumbs = [(f, s) for _, f, s in detect_photos(photos, list(range(len(photos))), small,
                                                  thumbnail=True, keep=keep)]
    found = [len(m) for m in match_pairs(
        [PairTask(thumbs[i][0], thumbs[j][0], opts, max(thumbs[i][1], thumbs[j][1]),
                  photos[i].photo, photos[j].photo) for i, j, _ in every], opts)]
    return [c for c, n in zip(every, found, strict=True) if n >= opts.min_matches]


def tie_points(photos: list[BlockPhoto], opts: TiePointOptions,
               progress: Progress | None = None) -> TiePointResult:
    """Run the pipeline (module docstring) on ``photos``, taken in id order: the candidate
    pairs, the union-find of the tracks and the thinning's ties would otherwise depend on the
    order the photos are listed in (371 or 387 points of one block); ``result.photos`` is in
    id order."""
    say = progress or (lambda p, m: None)
    if len(photos) < 2:
        raise InputDataError(f"tie points need at least two photos, got {len(photos)}")
    order = sorted(range(len(photos)), key=lambda k: (photos[k].id, str(photos[k].source.path)))
    photos = [photos[k] for k in order]
    if opts.positions is not None:  # one row per photo, in the photos' order
        opts = replace(opts, positions=np.asarray(opts.positions)[order])
    candidates, how = select_pairs(photos, opts)
    say(10, f"{len(candidates)} candidate pairs ({how})")
    used = sorted({k for i, j, _ in candidates for k in (i, j)})
    feats: dict[int, Features] = {}
    scales: dict[int, float] = {}
    for n, (k, f, s) in enumerate(detect_photos(photos, used, opts)):
        feats[k], scales[k] = f, s
        say(10 + 40 * (n + 1) / max(1, len(used)), f"features of {photos[k].id}: {len(f)}")
    # pairs are matched through the executor: local threads or a Dask cluster
    matched = match_pairs([PairTask(feats[i], feats[j], opts, max(scales[i], scales[j]),
                                    photos[i].photo, photos[j].photo)
                           for i, j, _ in candidates], opts)
    for bp in photos:
        bp.level = None  # photos in no candidate pair kept theirs
    reports: list[PairReport] = []
    verified: list[tuple[int, int, np.ndarray, np.ndarray, np.ndarray]] = []
    for (i, j, overlap), m in zip(candidates, matched, strict=True):
        rep = PairReport(photos[i].id, photos[j].id, overlap)
        ia, ib, res = m.ia, m.ib, m.f_residual
        rep.candidates, rep.median_f_residual_px = m.candidates, _median(res)
        pa, pb = photos[i].photo, photos[j].photo
        if len(ia) and pa is not None and pb is not None and pa.exterior is not None \
                and pb.exterior is not None:
            epi = matching.orientation_epipolar_distance(pa, pb, feats[i].xy[ia], feats[j].xy[ib])
            rep.median_epipolar_px = _median(epi)
            if opts.epipolar_tolerance is not None:
                ok = epi <= opts.epipolar_tolerance
                ia, ib, res = ia[ok], ib[ok], res[ok]
        rep.verified = len(ia)
        if rep.verified < opts.min_matches:
            rep.status = "no_matches" if rep.candidates < opts.min_matches else "not_verified"
            rep.verified = 0
        else:
            verified.append((i, j, ia, ib, m.model))
        reports.append(rep)
    say(60, f"{len(verified)} of {len(candidates)} pairs verified")
    tied = {k for i, j, *_ in verified for k in (i, j)}
    untied = [bp.id for k, bp in enumerate(photos) if k not in tied]
    if not verified:
        raise InputDataError(f"no photo pair of {len(photos)} photos could be tied "
                             f"({len(candidates)} candidate pairs, chosen by {how}): the photos "
                             "do not overlap or show no common texture")
    limit = max(len(f) for f in feats.values()) + 1
    found, dropped = tracks.build_tracks(((i, j, ia, ib) for i, j, ia, ib, _ in verified), limit)
    xy = [np.array([feats[p].xy[f] for p, f in t]) for t in found]
    # closure: every pair of a track's photos that has a fundamental matrix must agree with it
    # (a chain a-b-c of pairwise-correct matches can still join two different points)
    epipolar = {(i, j): f for i, j, _, _, f in verified}
    residual = _track_residuals(found, xy, epipolar)
    bad = residual > 2.0 * opts.f_threshold * max(scales.values())
    found = [t for t, b in zip(found, bad, strict=True) if not b]
    xy = [p for p, b in zip(xy, bad, strict=True) if not b]
    residual = residual[~bad]
    dropped += int(bad.sum())
    n_rays = np.array([len(t) for t in found])
    # the tracks of each model (pair), with their positions on its first photo: one pass
    # (every pair of photos that tracks share, matched directly or through a third photo)
    per_pair: dict[tuple[int, int], list[tuple[int, int, int]]] = {
        (i, j): [] for i, j, *_ in verified}
    for k, t in enumerate(found):
        photos_k = [p for p, _ in t]
        for a in range(len(photos_k)):
            for b in range(a + 1, len(photos_k)):
                per_pair.setdefault((photos_k[a], photos_k[b]), []).append((k, a, b))
    models = [(np.array([k for k, _, _ in per_pair[(i, j)]], int),
               np.array([xy[k][a] for k, a, _ in per_pair[(i, j)]]).reshape(-1, 2))
              for i, j, *_ in verified]
    # unrefined positions of every pair's tracks on both photos: the local affines of refinement
    common = {key: (np.array([xy[k][a] for k, a, _ in rows]).reshape(-1, 2),
                    np.array([xy[k][b] for k, _, b in rows]).reshape(-1, 2))
              for key, rows in per_pair.items()}
    keep = thinning.thin(models, n_rays, residual, opts.target_per_model)
    say(70, f"{len(found)} tracks, {int(keep.sum())} kept after thinning")
    result_tracks = []
    kept_idx = np.flatnonzero(keep)
    sources = {k: photos[k].source for k in used}
    runs = current_runs()

    def refined_track(k: int) -> tuple[np.ndarray, np.ndarray]:
        with working_for(runs):  # the warnings it logs are the run's
            return _refine_track(k, found, xy, sources, opts, scales, common, epipolar)

    # tracks refine independently: threads (OpenCV's remap and LAPACK release the GIL; reads
    # of one photo are serialised by its source's lock), or batches on a Dask cluster
    with ThreadPoolExecutor(opts.workers or os.cpu_count() or 1) as pool:
        on_cluster = opts.refine and getattr(opts.executor, "kind", "local") == "dask"
        done = refine_on_cluster(kept_idx, found, xy, photos, opts, scales, common, epipolar) \
            if on_cluster else pool.map(refined_track, kept_idx) if opts.refine else iter(())
        for n, k in enumerate(kept_idx):
            photo_idx = [p for p, _ in found[k]]
            pos = xy[k].copy()
            sigma = np.full(len(photo_idx), 0.5 * max(scales[p] for p in photo_idx))
            refined = False
            if opts.refine:
                pos, ok = next(done)
                photo_idx = [p for p, o in zip(photo_idx, ok, strict=True) if o]
                pos = pos[ok]
                sigma = np.full(len(photo_idx), 0.5)
                refined = True
            if len(photo_idx) >= 2:
                result_tracks.append(Track(photo_idx, pos, sigma, refined))
            if n % 50 == 0:
                say(70 + 25 * n / max(1, len(kept_idx)), "refining")
    for source in sources.values():
        source.close()
    _count_kept(reports, verified, result_tracks, photos, feats)
    return TiePointResult(photos, result_tracks, reports, untied, dropped,
                          {photos[k].id: len(feats[k]) for k in used}, how)


def _track_residuals(found: list, xy: list, models: dict) -> np.ndarray:
    """Per track, the largest symmetric epipolar distance (px) of its observations over every
    pair of its photos that has an epipolar model."""
    worst = np.zeros(len(found))
    members: dict[tuple[int, int], list[tuple[int, int, int]]] = {}
    for k, t in enumerate(found):
        photos = [p for p, _ in t]
        for a in range(len(photos)):
            for b in range(a + 1, len(photos)):
                if (photos[a], photos[b]) in models:
                    members.setdefault((photos[a], photos[b]), []).append((k, a, b))
    for key, rows in members.items():
        ks = np.array([r[0] for r in rows])
        xa = np.array([xy[k][a] for k, a, _ in rows])
        xb = np.array([xy[k][b] for k, _, b in rows])
        np.maximum.at(worst, ks, models[key].residual(xa, xb))
    return worst


#: tracks refined per task on a Dask cluster
REFINE_BATCH = 256


@dataclass(frozen=True)
class RefineTask:
    """Tracks to refine on a Dask worker: their observations, and only what they need: the
    photos' images (read there by their paths), level scales and cameras, and their pairs'
    local-affine support and epipolar models (without normalisers: functions, not picklable;
    the worker rebuilds them from the cameras)."""

    tracks: tuple[int, ...]
    found: dict
    xy: dict
    sources: dict
    cameras: dict
    opts: TiePointOptions
    scales: dict
    common: dict
    epipolar: dict


def refine_batch(task: RefineTask) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`_refine_track` of every track of a :class:`RefineTask` (on a worker: its
    photos' images are the worker's, kept across tasks by :func:`worker_image`)."""
    sources = {p: worker_image(s) for p, s in task.sources.items()}
    epipolar = {}
    for (a, b), model in task.epipolar.items():
        if model.kind == "E":
            model = replace(model, to_a=matching.normaliser(task.cameras[a]),
                            to_b=matching.normaliser(task.cameras[b]))
        epipolar[(a, b)] = model
    return [_refine_track(k, task.found, task.xy, sources, task.opts, task.scales,
                          task.common, epipolar) for k in task.tracks]


_WORKER_IMAGES: dict = {}
_WORKER_IMAGES_LOCK = threading.Lock()
WORKER_IMAGES = 8  # images a worker keeps (each up to ImageSource.WHOLE_LIMIT bytes of grey)


def worker_image(source: ImageSource) -> ImageSource:
    """The worker's own copy of ``source`` (same path, file, size and stretch), kept for its
    next tasks: a photo read whole for refinement is read once per worker, not per task. The
    oldest beyond :data:`WORKER_IMAGES` is dropped, not closed (a task of another thread may
    still read it; it is freed with its last task)."""
    from toolbox.raster.datasets import file_stamp

    try:
        key = (str(source.path), file_stamp(source.path), source.stretch)
    except OSError:
        return source
    with _WORKER_IMAGES_LOCK:
        kept = _WORKER_IMAGES.pop(key, None) or source
        _WORKER_IMAGES[key] = kept  # the most recent last
        while len(_WORKER_IMAGES) > WORKER_IMAGES:
            del _WORKER_IMAGES[next(iter(_WORKER_IMAGES))]
    return kept


def refine_on_cluster(kept_idx: np.ndarray, found: list, xy: list, photos: list[BlockPhoto],
                      opts: TiePointOptions, scales: dict, common: dict, epipolar: dict
                      ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """``(positions, ok)`` of every kept track, in order, refined in batches of
    :data:`REFINE_BATCH` tracks on the Dask cluster of ``opts.executor``
    (:func:`refine_batch`): the same results as threads (tests)."""
    from toolbox.executor import map_tiles

    executor, bare = _where(opts)

    def tasks() -> Iterator[RefineTask]:
        for start in range(0, len(kept_idx), REFINE_BATCH):
            batch = [int(k) for k in kept_idx[start:start + REFINE_BATCH]]
            used = {p for k in batch for p, _ in found[k]}
            pairs_of = {(found[k][0][0], p) for k in batch for p, _ in found[k][1:]}
            models = {key: replace(m, to_a=None, to_b=None)
                      for key, m in epipolar.items() if key in pairs_of or key[::-1] in pairs_of}
            yield RefineTask(tuple(batch), {k: found[k] for k in batch},
                             {k: xy[k] for k in batch}, {p: photos[p].source for p in used},
                             {p: photos[p].photo for p in used}, bare,
                             {p: scales[p] for p in used},
                             {key: common[key] for key in pairs_of if key in common}, models)

    for results in map_tiles(refine_batch, tasks(), executor=executor):
        yield from results


def _refine_track(k: int, found: list, xy: list, sources: dict[int, ImageSource],
                  opts: TiePointOptions, scales: dict[int, float], common: dict,
                  epipolar: dict) -> tuple[np.ndarray, np.ndarray]:
    """Refine every observation of track ``k`` against its first one; (positions, ok mask).

    A refined observation farther than the MAGSAC threshold from the epipolar line of the
    pair's estimated model (``epipolar``, when the pair has one) is dropped: on oblique views
    the correlation can lock onto a neighbouring structure (the detection-level match held)."""
    photo_idx = [p for p, _ in found[k]]
    pos = xy[k].copy()
    ok = np.ones(len(photo_idx), bool)
    ref = photo_idx[0]
    ref_xy = pos[0]
    radius = int(np.ceil(2 * max(scales[p] for p in photo_idx))) + 2
    for n, other in enumerate(photo_idx[1:], start=1):
        a_ref, a_oth = common.get((ref, other), (np.zeros((0, 2)), np.zeros((0, 2))))
        affine = refine.local_affine(a_ref, a_oth, ref_xy)
        if affine is None:
            ok[n] = False
            continue
        reach = opts.half + radius + 2
        extent_other = int(np.ceil(np.abs(affine).sum(axis=1).max() * reach)) + 2
        if not (_inside(sources[ref], ref_xy, opts.half + 2)
                and _inside(sources[other], pos[n], extent_other)):
            ok[n] = False  # a patch off the image would correlate with padding
            continue
        ro = _window(sources[ref], ref_xy, opts.half + 2)
        oo = _window(sources[other], pos[n], extent_other)
        r = refine.refine_pair(ro[0], ro[1], ref_xy, oo[0], oo[1], pos[n], affine, opts.half,
                               radius, opts.min_ncc)
        pos[n] = r.xy
        ok[n] = r.ok
        model = epipolar.get((ref, other)) if ref < other else epipolar.get((other, ref))
        if ok[n] and model is not None:
            pair = (pos[:1], pos[n:n + 1]) if ref < other else (pos[n:n + 1], pos[:1])
            limit = opts.f_threshold * max(scales[ref], scales[other])
            ok[n] = bool(model.residual(*pair)[0] <= limit)
    if not ok[1:].any():
        ok[0] = False
    return pos, ok


def _inside(source: ImageSource, centre: np.ndarray, half: int) -> bool:
    return bool(half <= centre[0] <= source.width - half and half <= centre[1] <= source.height - half)


def _window(source: ImageSource, centre: np.ndarray, half: int
            ) -> tuple[np.ndarray, tuple[int, int]]:
    c0 = int(np.floor(centre[0])) - half
    r0 = int(np.floor(centre[1])) - half
    return source.window(c0, r0, 2 * half + 2, 2 * half + 2), (c0, r0)


def _count_kept(reports: list[PairReport], verified: list, result: list[Track],
                photos: list[BlockPhoto], feats: dict[int, Features]) -> None:
    """Kept tie points per pair and how many 3 x 3 Gruber cells of the overlap they cover (the
    overlap's box: the pair's verified matches on its first photo)."""
    index = {(photos[i].id, photos[j].id): (i, j, ia) for i, j, ia, *_ in verified}
    for rep in reports:
        if (rep.a, rep.b) not in index:
            continue
        i, j, ia = index[(rep.a, rep.b)]
        pts = np.array([t.xy[t.photos.index(i)] for t in result
                        if i in t.photos and j in t.photos]).reshape(-1, 2)
        rep.kept = len(pts)
        box = feats[i].xy[ia]
        rep.cells_3x3 = thinning.coverage_3x3(pts, box.min(axis=0), box.max(axis=0))
