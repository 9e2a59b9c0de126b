"""Named ultrasonic sensor configurations (the figures each comes from are cited beside it).

- ``open_40khz``: an open-type 40 kHz air transducer of the Murata MA40S4S
  class (Murata ultrasonic sensor application manual, cat. S15E: 40 kHz,
  directivity 80 deg total at -6 dB, 120 dB SPL re 20 uPa at 30 cm with
  10 Vrms, detectable range 0.2-4 m). The piston radius 4.71 mm gives the
  80 deg -6 dB beam at 40 kHz and 20 deg C. Its bandwidth is not in that
  catalogue; Q = 34.6 is that of the Pro-Wave 400PT120 of the same class
  (40.0 kHz, -6 dB bandwidth 2.0 kHz: 2 Q (1 kHz) / f0 = sqrt(3)).
- ``parking_40khz``: a closed (aluminium housing) 40 kHz parking-aid
  transducer (vendor datasheet of a car reversing-aid sensor: 40.0 kHz,
  117 dB SPL re 20 uPa at 30 cm, -6 dB directivity 50 deg, ringing
  <= 1.2 ms); rear-sonar range 0.25-2.5 m (Murata application notes give
  2-2.5 m for rear sonar). Radius 7.16 mm for the 50 deg beam.
- ``ring8_40khz``: eight ``open_40khz`` transducers on a 0.15 m ring of a
  mobile base, 45 deg apart, fired one after the other, each at 15 Hz
  (120 firings per second); each listens 8.2 ms (1.4 m) before the next
  fires. The 80 deg beams overlap at 45 deg spacing, so neighbours hear
  each other's echoes.

Source pressure at 1 m: SPL at 0.3 m, p = 20 uPa 10^(SPL / 20) sqrt(2)
(amplitude of the rms level), times 0.3 (spherical spreading; the far field
starts at a^2 / lambda ~ 3 mm). Ring-down: the level at the burst's end that
decays to the threshold at the datasheet's ringing time (or minimum range),
ringdown = threshold(0) exp(t_ring / tau). Noise: 1 mPa rms in band, a
preamplifier of ~10 nV / sqrt(Hz) over the 2 kHz band at the transducer's
~0.7 mV / Pa (MA40S4S: -63 dB re 1 V / Pa).
"""

from __future__ import annotations

import math

from twinsense.ultrasonic.acoustics import radius_for_beam_angle, speed_of_sound
from twinsense.ultrasonic.config import UltrasonicConfig, ring_poses
from twinsense.ultrasonic.signal import time_constant

_C20 = speed_of_sound(20.0)
_Q = math.sqrt(3.0) * 40.0 / 2.0  # Pro-Wave 400PT120: -6 dB at +-1 kHz around 40 kHz


def _p1m(spl_db_at_30cm: float) -> float:
    """On-axis pressure amplitude at 1 m [Pa] of a level SPL [dB re 20 uPa rms] measured at 0.3 m."""
    return 20e-6 * 10 ** (spl_db_at_30cm / 20) * math.sqrt(2.0) * 0.3


def _ringdown(threshold0: float, ring_time: float, f: float = 40e3) -> float:
    """Ring level at the burst's end that decays to ``threshold0`` ``ring_time`` [s] after it."""
    return threshold0 * math.exp(ring_time / time_constant(f, _Q))


_OPEN = UltrasonicConfig(
    frequency=40e3, aperture_radius=radius_for_beam_angle(80.0, 40e3, _C20), n_cycles=8, q_factor=_Q,
    source_pressure=_p1m(120.0),
    # minimum range 0.2 m: the ring reaches the threshold 2 x 0.2 m / c after firing (burst 0.2 ms)
    ringdown_pa=_ringdown(0.02, 2 * 0.2 / _C20 - 8 / 40e3), noise_pa=1e-3, sample_rate=400e3,
    max_range=4.0, frame_rate=20.0, threshold=((0.0, 0.02), (1.0, 0.01), (4.0, 0.005)))

PRESETS: dict[str, tuple[UltrasonicConfig, str]] = {
    "open_40khz": (_OPEN, "open-type 40 kHz transducer (MA40S4S class): 80 deg beam, 0.2-4 m, 20 Hz"),
    "parking_40khz": (UltrasonicConfig(
        frequency=40e3, aperture_radius=radius_for_beam_angle(50.0, 40e3, _C20), n_cycles=16, q_factor=_Q,
        source_pressure=_p1m(117.0), ringdown_pa=_ringdown(0.03, 1.2e-3), noise_pa=1e-3,
        sample_rate=400e3, max_range=2.5, frame_rate=20.0, threshold=((0.0, 0.03), (2.5, 0.01))),
        "closed aluminium 40 kHz parking-aid transducer: 50 deg beam, 1.2 ms ringing, 0.25-2.5 m, 20 Hz"),
    "ring8_40khz": (UltrasonicConfig(
        frequency=_OPEN.frequency, aperture_radius=_OPEN.aperture_radius, n_cycles=8, q_factor=_Q,
        source_pressure=_OPEN.source_pressure, ringdown_pa=_OPEN.ringdown_pa, noise_pa=1e-3,
        sample_rate=200e3, max_range=1.4, frame_rate=15.0, transducers=ring_poses(8, 0.15),
        threshold=((0.0, 0.02), (1.4, 0.01))),
        "8 open 40 kHz transducers on a 0.15 m ring, fired in turn, 15 Hz each (120 firings/s), 1.4 m"),
}
