"""Configuration of an ultrasonic sensor: one transducer or a ring fired in sequence."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.scene.pose import Pose
from twinsense.ultrasonic import acoustics as A
from twinsense.ultrasonic import signal as S


@dataclass(frozen=True)
class UltrasonicConfig:
    """A pulse-echo ultrasonic sensor with one or more transducers (a ring) firing one after the other.

    Parameters
    ----------
    frequency : float
        Transducer resonance and burst frequency [Hz].
    aperture_radius : float
        Piston radius [m] along the transducer's x axis (sets the beam, see
        :func:`acoustics.radius_for_beam_angle`).
    aperture_radius_y : float or None
        Piston semi-axis along y [m] for an elliptical beam; None: circular.
    n_cycles : int
        Cycles in the transmit burst.
    q_factor : float
        Quality factor of the transducer resonance (each way).
    source_pressure : float
        On-axis far-field sound pressure amplitude at 1 m [Pa] for a long burst.
    ringdown_pa : float
        The transmitter's ringing at the end of the burst, in the receiver's
        equivalent pressure [Pa]; it decays with tau = Q / (pi f).
    noise_pa : float
        Receiver noise, rms in the transducer band, equivalent pressure [Pa].
    sample_rate : float
        A-scan sample rate [Hz] (> 2 x frequency).
    max_range : float
        Listening window of each firing, as a range [m]: 2 max_range / c.
    frame_rate : float
        Firing cycles per second [Hz]: every transducer fires once per cycle,
        the N transducers evenly spaced in time (interval 1 / (N frame_rate)).
    transducers : tuple of Pose
        Transducer poses in the sensor frame (boresight = the pose's z axis).
    threshold : tuple of (range [m], level [Pa])
        Detection threshold map, linear in range between the points.
    temperature_c, relative_humidity, pressure : float
        Air: [deg C], [%], [Pa] (speed of sound and ISO 9613-1 absorption).
    late_echo_range : float
        Echoes of earlier firings are followed up to this range [m]: they are
        the late echoes and cross-talk that reach later listening windows.
    """

    frequency: float = 40e3
    aperture_radius: float = 4.7e-3
    aperture_radius_y: float | None = None
    n_cycles: int = 8
    q_factor: float = 34.6
    source_pressure: float = 6.0
    ringdown_pa: float = 1.0
    noise_pa: float = 1e-3
    sample_rate: float = 400e3
    max_range: float = 4.0
    frame_rate: float = 20.0
    transducers: tuple = field(default_factory=lambda: (Pose(),))
    threshold: tuple = ((0.0, 0.02), (4.0, 0.005))
    temperature_c: float = 20.0
    relative_humidity: float = 50.0
    pressure: float = 101_325.0
    late_echo_range: float = 6.0

    def __post_init__(self):
        p = "UltrasonicConfig"
        V.number(f"{p}.frequency", self.frequency, lo=1e3, hi=1e6, unit="Hz")
        V.number(f"{p}.aperture_radius", self.aperture_radius, lo=1e-4, hi=0.5, unit="m")
        if self.aperture_radius_y is not None:
            V.number(f"{p}.aperture_radius_y", self.aperture_radius_y, lo=1e-4, hi=0.5, unit="m")
        V.integer(f"{p}.n_cycles", self.n_cycles, lo=1, hi=1000)
        V.number(f"{p}.q_factor", self.q_factor, lo=1.0, hi=1e4)
        V.positive(f"{p}.source_pressure", self.source_pressure, "Pa at 1 m")
        V.non_negative(f"{p}.ringdown_pa", self.ringdown_pa, "Pa")
        V.non_negative(f"{p}.noise_pa", self.noise_pa, "Pa")
        V.number(f"{p}.sample_rate", self.sample_rate, lo=2 * self.frequency, lo_open=True, hi=1e8,
                 unit="Hz, above twice the frequency")
        V.number(f"{p}.max_range", self.max_range, lo=0.0, lo_open=True, hi=100.0, unit="m")
        V.positive(f"{p}.frame_rate", self.frame_rate, "Hz")
        V.number(f"{p}.late_echo_range", self.late_echo_range, lo=0.0, hi=1000.0, unit="m")
        V.number(f"{p}.temperature_c", self.temperature_c, lo=-50.0, hi=80.0, unit="deg C")
        V.number(f"{p}.relative_humidity", self.relative_humidity, lo=0.0, hi=100.0, unit="%")
        V.number(f"{p}.pressure", self.pressure, lo=5e4, hi=1.2e5, unit="Pa")
        tr = self.transducers
        if isinstance(tr, Pose):
            tr = (tr,)
        if not isinstance(tr, (tuple, list)) or not tr or not all(isinstance(x, Pose) for x in tr):
            raise ConfigError(f"{p}.transducers", tr, "a non-empty sequence of Pose (transducer -> sensor)")
        object.__setattr__(self, "transducers", tuple(tr))
        thr = self.threshold
        try:
            pts = np.asarray(thr, dtype=float)
        except (TypeError, ValueError):
            pts = np.zeros((0, 0))
        if (pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0 or not np.all(np.isfinite(pts))
                or np.any(pts[:, 1] <= 0) or np.any(np.diff(pts[:, 0]) <= 0) or pts[0, 0] < 0):
            raise ConfigError(f"{p}.threshold", thr, "(range [m], level [Pa]) pairs, ranges >= 0 increasing, "
                                                     "levels > 0")
        object.__setattr__(self, "threshold", tuple((float(r), float(v)) for r, v in pts))
        listen = 2 * self.max_range / self.speed_of_sound
        if listen > self.firing_interval * (1 + 1e-9):
            limit = 0.5 * self.speed_of_sound * self.firing_interval
            raise ConfigError(f"{p}.max_range", self.max_range,
                              f"<= {limit:.3f} m: the listening window 2 max_range / c must end before the next "
                              f"firing ({len(self.transducers)} transducers at {self.frame_rate:g} Hz)")

    # Derived quantities (no state: computed from the fields).
    @property
    def n_transducers(self) -> int:
        return len(self.transducers)

    @cached_property
    def speed_of_sound(self) -> float:
        """c [m/s] at ``temperature_c``."""
        return A.speed_of_sound(self.temperature_c)

    @property
    def wavenumber(self) -> float:
        return 2 * math.pi * self.frequency / self.speed_of_sound

    @property
    def wavelength(self) -> float:
        return self.speed_of_sound / self.frequency

    @cached_property
    def absorption_db_per_m(self) -> float:
        """ISO 9613-1 attenuation at the burst frequency [dB/m]."""
        return float(A.air_absorption_db_per_m(self.frequency, self.temperature_c, self.relative_humidity,
                                               self.pressure))

    @property
    def firing_interval(self) -> float:
        """Time between two consecutive firings [s]: 1 / (N frame_rate)."""
        return 1.0 / (self.n_transducers * self.frame_rate)

    @property
    def burst_duration(self) -> float:
        return self.n_cycles / self.frequency

    @property
    def tau(self) -> float:
        """Envelope time constant of the resonance [s]."""
        return S.time_constant(self.frequency, self.q_factor)

    @property
    def n_samples(self) -> int:
        """A-scan samples per firing (the listening window 2 max_range / c)."""
        return math.ceil(2 * self.max_range / self.speed_of_sound * self.sample_rate)

    @property
    def ka(self) -> tuple[float, float]:
        ay = self.aperture_radius if self.aperture_radius_y is None else self.aperture_radius_y
        return self.wavenumber * self.aperture_radius, self.wavenumber * ay

    @property
    def beam_angle_deg(self) -> tuple[float, float]:
        """Total -6 dB beam angles [deg] in the transducer's x-z and y-z planes."""
        ay = self.aperture_radius if self.aperture_radius_y is None else self.aperture_radius_y
        return (A.beam_angle_deg(self.aperture_radius, self.frequency, self.speed_of_sound),
                A.beam_angle_deg(ay, self.frequency, self.speed_of_sound))

    def threshold_at_range(self, r) -> np.ndarray:
        pts = np.asarray(self.threshold)
        return np.interp(r, pts[:, 0], pts[:, 1])

    @property
    def min_range(self) -> float:
        """Range [m] blinded by the ring-down: c t_b / 2 with t_b where the ringing meets the threshold."""
        c = self.speed_of_sound
        tb = S.blanking_time(self.burst_duration, self.tau, self.ringdown_pa,
                             lambda t: float(self.threshold_at_range(0.5 * c * t)))
        return 0.5 * c * tb

    def to_dict(self) -> dict:
        return {"frequency": self.frequency, "aperture_radius": self.aperture_radius,
                "aperture_radius_y": self.aperture_radius_y, "n_cycles": self.n_cycles,
                "q_factor": self.q_factor, "source_pressure": self.source_pressure,
                "ringdown_pa": self.ringdown_pa, "noise_pa": self.noise_pa, "sample_rate": self.sample_rate,
                "max_range": self.max_range, "frame_rate": self.frame_rate,
                "transducers": [p.to_dict() for p in self.transducers],
                "threshold": [list(p) for p in self.threshold], "temperature_c": self.temperature_c,
                "relative_humidity": self.relative_humidity, "pressure": self.pressure,
                "late_echo_range": self.late_echo_range}


def ring_poses(n: int, radius: float) -> tuple[Pose, ...]:
    """``n`` transducers evenly around a ring of ``radius`` [m] in the sensor's x-z plane, facing outwards.

    Transducer i points at angle 360 i / n deg from the sensor's z axis
    towards +x (sensor frame: x right, y down, z forward; a sensor mounted
    with a horizontal z then has a horizontal ring, transducer 0 forward).
    """
    n = V.integer("ring.n", n, lo=1, hi=64)
    radius = V.non_negative("ring.radius", radius, "m")
    out = []
    for i in range(n):
        phi = 2 * math.pi * i / n
        s, c = math.sin(phi), math.cos(phi)
        rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # rotation about y: z -> (sin, 0, cos)
        out.append(Pose(np.array([radius * s, 0.0, radius * c]), rot))
    return tuple(out)
