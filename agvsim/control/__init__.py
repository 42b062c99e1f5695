"""Path following for the AGV."""
from agvsim.control.pure_pursuit import FollowerParams, PurePursuit, RoutePath

__all__ = ["FollowerParams", "PurePursuit", "RoutePath"]
