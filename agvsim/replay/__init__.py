"""Logged drives: read a real vehicle's drive (a plain folder or a ROS 2 bag), write a simulated
one, and run the localizer and filter along it (``agvsim track``).

:mod:`agvsim.replay.drive` (the log and the vehicle file), :mod:`agvsim.replay.folder` and
:mod:`agvsim.replay.bag` (the two formats), :mod:`agvsim.replay.export` (a closed loop written as
a log as it runs), :mod:`agvsim.replay.track` (the replay).
"""
