"""Stereo pairs: epipolar resampling."""
