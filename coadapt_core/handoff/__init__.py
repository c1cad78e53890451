"""From a run's chosen design to a robot: the handoff folder (`coadapt handoff`) with the
design's model files, its controller as ONNX and its design sheet (docs/handoff.md)."""
