"""Suite-wide test settings.

Hypothesis: under CI (``CI`` set, as ``.ci/run`` is run) the property tests
are derandomized, so a run is reproducible and CI cannot fail on an example
no one can replay. Locally they explore new random examples each run (and
replay failures from ``.hypothesis/``), which is how misses are found.
"""
import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "default")
