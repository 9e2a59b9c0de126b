"""Recordings, device file formats and streams."""

from twinsense.io.recording import Recording, RecordingWriter, SensorRecording, open_recording

__all__ = ["Recording", "RecordingWriter", "SensorRecording", "open_recording"]
