"""A frame as the detector reads it: files and video frames in, area-averaged pyramid levels and the
sharpened copy that the search runs on.
"""
