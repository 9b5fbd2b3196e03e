"""The WGS84 -> grid transformer of toolbox.exchange.geodesy is made once per CRS: reading an
OpenSfM reconstruction (ortho:batch reads ODM's twice: the runner's input check, then the
photos) made the same one three times a read, each a PROJ database query (3-4 ms; 0.018 against
0.003 s CPU for the second read). The values are pyproj's own, on every thread."""

from __future__ import annotations

import numpy as np
import pyproj
from pyproj import CRS, Transformer

from tests.helpers_threads import run_in_threads
from toolbox.exchange import geodesy

UTM = CRS.from_epsg(32633)
LON, LAT = np.array([14.25, 14.5, 15.0]), np.array([45.1, 45.4, 46.0])
H = np.array([10.0, 250.0, 900.0])


def test_one_transformer_per_crs_with_pyprojs_values(monkeypatch):
    getattr(geodesy._geographic_to, "cache_clear", lambda: None)()
    made = []
    real = Transformer.from_crs

    def counting(source, target, **kwargs):
        made.append((str(source), str(target)))
        return real(source, target, **kwargs)

    monkeypatch.setattr(pyproj.Transformer, "from_crs", staticmethod(counting))
    ours = geodesy.geographic_to_grid(LON, LAT, H, UTM)
    again = geodesy.geographic_to_grid(LON, LAT, H, CRS.from_epsg(32633))
    back = geodesy.grid_to_geographic(ours, UTM)
    geodesy.topocentric_function(LAT[0], LON[0], H[0], UTM)(np.zeros((1, 3)))
    monkeypatch.undo()
    assert len(made) == 1
    reference = real("EPSG:4979", UTM, always_xy=True)
    np.testing.assert_array_equal(ours, np.column_stack(reference.transform(LON, LAT, H)))
    np.testing.assert_array_equal(again, ours)
    np.testing.assert_allclose(back, np.column_stack([LON, LAT, H]), atol=1e-9)
    # the one transformer, made on this thread, on four others at once: pyproj's values
    results = []

    def work():
        for _ in range(50):
            results.append(geodesy.geographic_to_grid(LON, LAT, H, UTM))

    run_in_threads(*[work] * 4)
    assert len(results) == 200
    for r in results:
        np.testing.assert_array_equal(r, ours)
