"""Duplicate-XY merging rules and the local origin."""

import numpy as np
import pytest

from toolbox.terrain.points import local_origin, merge_duplicate_xy

XYZ = np.array([[0, 0, 1], [1, 1, 2], [0, 0, 3], [2, 2, 5], [1, 1, 2.0]])


@pytest.mark.parametrize("rule, z", [("mean", [2, 2, 5]), ("first", [1, 2, 5]),
                                     ("min", [1, 2, 5]), ("max", [3, 2, 5])])
def test_rules_keep_first_occurrence_order(rule, z):
    merged, report, keep = merge_duplicate_xy(XYZ, rule=rule)
    np.testing.assert_array_equal(merged[:, :2], [[0, 0], [1, 1], [2, 2]])
    np.testing.assert_array_equal(merged[:, 2], z)
    assert list(keep) == [0, 1, 3]
    assert (report.groups, report.removed, report.max_z_spread) == (2, 2, 2.0)


def test_error_rule_names_the_position():
    with pytest.raises(ValueError, match="x=0.000 y=0.000: z from 1.000 to 3.000"):
        merge_duplicate_xy(XYZ, rule="error")
    merge_duplicate_xy(XYZ[[1, 4, 3]], rule="error")  # same Z twice is not a conflict


def test_tolerance_merges_near_points_to_their_mean():
    xyz = np.array([[0, 0, 1], [0.01, 0, 3], [5, 5, 0]])
    merged, report, _ = merge_duplicate_xy(xyz, tolerance=0.05)
    np.testing.assert_allclose(merged, [[0.005, 0, 2], [5, 5, 0]])
    assert report.removed == 1


def test_no_duplicates_is_identity_and_origin_is_round():
    xyz = np.array([[1688000.3, 4799500.2, 1], [1689000, 4800300, 2]])
    merged, report, _ = merge_duplicate_xy(xyz)
    np.testing.assert_array_equal(merged, xyz)
    assert report.removed == 0
    np.testing.assert_array_equal(local_origin(xyz), [1688500, 4799900])
