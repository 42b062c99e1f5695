"""Measuring a target found: its sub-pixel edges, the perspective-exact pose fitted to them with its
covariance, the photometric refinement, and the observation it becomes.
"""
