"""What a live stream carries of one frame: named arrays.

The recorded streams (``frame.streams()``, the same arrays the HDF5
recording stores) plus what a frame derives but the recording does not
keep: a radar's detections, as ``detections.<field>`` arrays.
"""

from __future__ import annotations

import numpy as np

#: Radar detection arrays published beside the recorded streams: name -> RadarPointCloud attribute.
#: points [m] (n, 3) in the optical sensor frame; range [m]; velocity [m/s] radial, positive away;
#: snr_db [dB]; azimuth, elevation [rad].
DETECTION_FIELDS = {"detections.points": "points_sensor", "detections.range": "range",
                    "detections.velocity": "velocity", "detections.snr_db": "snr_db",
                    "detections.azimuth": "azimuth", "detections.elevation": "elevation"}


def frame_arrays(frame) -> dict[str, np.ndarray]:
    """Named C-contiguous arrays of ``frame``: its streams, then any derived arrays (shapes as documented
    on the frame class; detections as :data:`DETECTION_FIELDS`)."""
    out = {k: np.ascontiguousarray(v) for k, v in frame.streams().items()}
    det = getattr(frame, "detections", None)
    if det is not None and hasattr(det, "points_sensor"):
        for key, attr in DETECTION_FIELDS.items():
            out[key] = np.ascontiguousarray(getattr(det, attr), dtype=np.float64)
    return out
