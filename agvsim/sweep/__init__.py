"""Sweeps: a drift study over many settings (``agvsim sweep``).

:mod:`~agvsim.sweep.spec` reads the spec (base drive, axes, seeds), :mod:`~agvsim.sweep.runs`
is one run (a point's drive for one seed, as one row), :mod:`~agvsim.sweep.engines` runs them
on a local process pool or on Ray, :mod:`~agvsim.sweep.folder` keeps each row the moment it
ends, :mod:`~agvsim.sweep.report` writes the table, the summary and the plots.
"""
