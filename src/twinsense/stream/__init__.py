"""Live streams of a running simulation: the sink protocol, ZeroMQ and Foxglove transports, the paced run.

``twinsense serve scenario.yaml`` runs a scenario paced to wall time and
publishes every frame (docs/streaming.md). The transports need the
``stream`` extra (pyzmq, foxglove-sdk) and are imported when first used.
"""

from __future__ import annotations

from typing import Any

from twinsense.stream.frames import frame_arrays
from twinsense.stream.serve import ServeResult, serve, serve_scenario
from twinsense.stream.sinks import FrameSink, QueuedSink

_LAZY = {"ZmqSink": "twinsense.stream.zeromq", "Subscriber": "twinsense.stream.zeromq",
         "StreamFrame": "twinsense.stream.zeromq", "FoxgloveSink": "twinsense.stream.foxglove_ws"}

__all__ = ["FrameSink", "QueuedSink", "ServeResult", "serve", "serve_scenario", "frame_arrays", *_LAZY]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'twinsense.stream' has no attribute {name!r}")
