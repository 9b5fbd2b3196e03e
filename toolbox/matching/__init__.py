"""Automatic image measurement: tie points across a block of photos and fiducial marks on scans.

Modules (kernels take arrays, never files, except :mod:`images`):

- :mod:`images`: windowed/decimated reading of (big) scans as 8-bit grey levels;
- :mod:`features`: keypoints and descriptors on a reduced level, tile by tile (OpenCV);
- :mod:`pairs`: which photo pairs to match (footprint overlap, or thumbnails);
- :mod:`matching`: ratio test, USAC/MAGSAC fundamental matrix, epipolar distance;
- :mod:`refine`: sub-pixel NCC refinement on full-resolution patches;
- :mod:`tracks`: union-find tracks, inconsistent ones dropped;
- :mod:`thinning`: Gruber-like cells per overlap, multi-ray points first;
- :mod:`block`: the whole tie-point pipeline for a block; :mod:`inputs`, :mod:`outputs`: its
  photos in, its measurement CSV, pair table and intersected points out;
- :mod:`ncc`: normalised cross-correlation with a sub-pixel peak and the runner-up;
- :mod:`marks`, :mod:`fiducial_search`, :mod:`fiducial_thumbs`: fiducial marks on scans;
- :mod:`chips`: control points predicted on photos, with image chips.
"""
