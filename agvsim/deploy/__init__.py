"""Deployment tools: where to hang targets (planner) and how to print them (:mod:`agvsim.deploy.printing`).

This package reads maps and target geometry and produces what a plant engineer takes onto the
floor; it imports the simulator's layers below it and :mod:`localizer`, never the commands or the
environments. It imports nothing itself: import the module you need.
"""
