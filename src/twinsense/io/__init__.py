"""The twinsense HDF5 recording: writer and reader.

Device files of real sensors live in radar/formats.py and radar/captures.py.
"""

from twinsense.io.recording import Recording, RecordingWriter, SensorRecording, open_recording

__all__ = ["Recording", "RecordingWriter", "SensorRecording", "open_recording"]
