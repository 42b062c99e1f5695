"""Runs as Rerun recordings (the ``record`` extra: ``pip install agvsim[record]``).

:class:`RunRecording` writes one recording to an ``.rrd`` file on the ``sim_time`` timeline,
under the entity paths of :data:`ENTITY_PATHS`; :class:`LoopRecorder` feeds it from a closed loop
(``agvsim demo --record``, ``agvsim drift --record``), :class:`RerunRecorder` from a Gymnasium
environment's episodes, and ``agvsim track --record`` from a logged drive. Open a file with
``rerun run.rrd``.
"""
from agvsim.record.process import RunRecording
from agvsim.record.recording import ENTITY_PATHS, TIMELINE
from agvsim.record.observer import LoopRecorder
from agvsim.record.gym import RerunRecorder

__all__ = ["ENTITY_PATHS", "TIMELINE", "LoopRecorder", "RerunRecorder", "RunRecording"]
