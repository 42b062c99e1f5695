"""The camera and the target: their geometry, the detector's parameters and what an observation
holds (SI units; thesis sign conventions: beta > 0 right of the optical axis, alpha > 0 when the
target's right edge is nearer).
"""
