"""Stereo pairs: epipolar (normalised) resampling and dense matching to surfaces."""
