"""Pictures of the simulated world (no OpenGL here: OpenCV drawing only)."""
from agvsim.views.topdown import TopDownView, Trajectory

__all__ = ["TopDownView", "Trajectory"]
