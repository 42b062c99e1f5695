"""Around the detector: camera calibration from chessboard photos, exact synthetic frames for tests
and benchmarks, and annotated pictures of what was found.
"""
