"""The one counters base (toolbox.counters): sums, maxima and dicts over windows, by hand."""

from __future__ import annotations

from toolbox.ortho.metrics import TileStatistics
from toolbox.raster.warp import WarpStatistics
from toolbox.terrain.tin.cutfill import CutFill


def test_tile_statistics_sum_counts_keep_the_largest_relief_and_merge_blocks():
    a = TileStatistics(cells=10, outside_dem=1, outside_photo=2, hidden=3, max_relief_m=4.5,
                       blocks={0: 1, 1: 2, 2: 0})
    a.add(TileStatistics(cells=5, outside_dem=0, outside_photo=1, hidden=0, max_relief_m=2.0,
                         blocks={0: 0, 1: 1, 2: 7}))
    assert (a.cells, a.outside_dem, a.outside_photo, a.hidden) == (15, 1, 3, 3)
    assert a.max_relief_m == 4.5 and a.blocks == {0: 1, 1: 3, 2: 7}


def test_warp_statistics_and_cut_fill_sum_every_field():
    w = WarpStatistics(windows=2, empty_windows=1, split_windows=0, source_pixels_read=100,
                       output_pixels=64)
    w.add(WarpStatistics(windows=3, empty_windows=0, split_windows=1, source_pixels_read=50,
                         output_pixels=36))
    assert w.as_dict() == {"windows": 5, "empty_windows": 1, "split_windows": 1,
                           "source_pixels_read": 150, "output_pixels": 100}
    c = CutFill(cut_volume=3.0, fill_volume=1.0, cut_area=2.0, fill_area=1.0, area=4.0)
    c += CutFill(cut_volume=1.0, fill_volume=4.0, cut_area=1.0, fill_area=2.0, area=3.0)
    assert c.as_dict() == {"cut_volume": 4.0, "fill_volume": 5.0, "net_volume": -1.0,
                           "cut_area": 3.0, "fill_area": 3.0, "area": 7.0}
