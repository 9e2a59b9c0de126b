"""Antenna elements and arrays of an FMCW radar (sensor frame).

Positions are in the sensor's optical frame (x right, y down, z forward =
boresight), in metres, one row per element. Element gains are power gains
(linear) of the form ``G0 * cos(az)**q_az * cos(el)**q_el`` — the usual
cos^q model of a patch element (Balanis, *Antenna Theory*, ch. 14) — with
azimuth = atan2(x, z) and elevation = atan2(-y, hypot(x, z)).

TDM-MIMO: chirp ``m`` of a frame is sent by transmitter
``tx_sequence[m % len(tx_sequence)]``; the virtual array is the set of
``tx + rx`` position sums, ordered (tx slot, rx) as the processing expects.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError

"""Speed of light in vacuum [m/s]."""


@dataclass(frozen=True)
class ElementPattern:
    """Power pattern of one antenna element: ``G0 cos(az)^q_az cos(el)^q_el``.

    Attributes
    ----------
    gain_dbi : float
        Peak (boresight) gain [dBi].
    cos_exponent_azimuth, cos_exponent_elevation : float
        Exponents q >= 0 of the cosine roll-off in azimuth and elevation
        (q = 0: isotropic in that plane). Zero gain behind the array (|angle| >= 90 deg).
    """

    gain_dbi: float = 5.0
    cos_exponent_azimuth: float = 1.0
    cos_exponent_elevation: float = 1.0

    def __post_init__(self) -> None:
        V.number("ElementPattern.gain_dbi", self.gain_dbi, lo=-30, hi=50, unit="dBi")
        V.number("ElementPattern.cos_exponent_azimuth", self.cos_exponent_azimuth, lo=0, hi=1000)
        V.number("ElementPattern.cos_exponent_elevation", self.cos_exponent_elevation,
                 lo=0, hi=1000)

    def gain(self, directions: np.ndarray) -> np.ndarray:
        """Linear power gain towards ``directions``.

        Parameters
        ----------
        directions : (n, 3) float
            Vectors in the sensor frame (need not be unit length).

        Returns
        -------
        (n,) float
            Linear power gain (0 behind the array).
        """
        d = np.asarray(directions, dtype=float)
        x, y, z = d[:, 0], d[:, 1], d[:, 2]
        # cos(az) = z / hypot(x, z) and cos(el)^2 = (x^2 + z^2) / |d|^2, with
        # squares instead of hypot (several times faster, same to ~1e-16).
        h2 = x * x
        h2 += z * z
        g = np.full(len(d), 10.0 ** (self.gain_dbi / 10.0))
        front = z > 0  # cos(az) > 0
        with np.errstate(invalid="ignore", divide="ignore"):
            if self.cos_exponent_azimuth:
                cos_az = np.where(front, z / np.sqrt(h2), 0.0)
                g *= cos_az if self.cos_exponent_azimuth == 1 else cos_az ** self.cos_exponent_azimuth
            else:
                g *= front
            if self.cos_exponent_elevation:
                r2 = h2 + y * y
                cos_el2 = np.divide(h2, r2, out=np.zeros(len(h2)), where=r2 > 0)
                g *= cos_el2 ** (0.5 * self.cos_exponent_elevation)
        return g


@dataclass(frozen=True, eq=False)
class AntennaArray:
    """Transmit and receive elements of a radar, sensor frame.

    Attributes
    ----------
    tx_positions : (n_tx, 3) float
        Transmit element phase centres [m].
    rx_positions : (n_rx, 3) float
        Receive element phase centres [m].
    tx_pattern, rx_pattern : ElementPattern
        Pattern shared by all transmit / all receive elements.
    tx_sequence : tuple of int
        TDM-MIMO order: chirp m is sent by ``tx_sequence[m % len(tx_sequence)]``
        (indices into ``tx_positions``). Default: every transmitter once, in order.
    """

    tx_positions: np.ndarray
    rx_positions: np.ndarray
    tx_pattern: ElementPattern = field(default_factory=ElementPattern)
    rx_pattern: ElementPattern = field(default_factory=ElementPattern)
    tx_sequence: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        tx = V.array("AntennaArray.tx_positions", self.tx_positions, (None, 3), unit="m")
        rx = V.array("AntennaArray.rx_positions", self.rx_positions, (None, 3), unit="m")
        if len(tx) < 1:
            raise ConfigError("AntennaArray.tx_positions", "array of shape (0, 3)",
                              "at least one transmit element, shape (n_tx, 3) [m]")
        if len(rx) < 1:
            raise ConfigError("AntennaArray.rx_positions", "array of shape (0, 3)",
                              "at least one receive element, shape (n_rx, 3) [m]")
        for name, arr in (("tx_positions", tx), ("rx_positions", rx)):
            if np.max(np.abs(arr)) > 1.0:
                raise ConfigError(f"AntennaArray.{name}", arr.tolist(),
                                  "element positions within 1 m of the sensor origin [m]")
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        for name in ("tx_pattern", "rx_pattern"):
            if not isinstance(getattr(self, name), ElementPattern):
                raise ConfigError(f"AntennaArray.{name}", getattr(self, name), "an ElementPattern")
        seq = self.tx_sequence
        if seq is None:
            seq = tuple(range(len(tx)))
        try:
            seq = tuple(int(V.integer("AntennaArray.tx_sequence[i]", s, lo=0, hi=len(tx) - 1))
                        for s in seq)
        except TypeError:
            raise ConfigError("AntennaArray.tx_sequence", self.tx_sequence,
                              "a sequence of transmitter indices") from None
        except ConfigError:
            raise ConfigError("AntennaArray.tx_sequence", self.tx_sequence,
                              f"indices into tx_positions, each in 0..{len(tx) - 1}") from None
        if not seq:
            raise ConfigError("AntennaArray.tx_sequence", self.tx_sequence,
                              "at least one transmitter index")
        object.__setattr__(self, "tx_sequence", seq)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, AntennaArray):
            return NotImplemented
        return (np.array_equal(self.tx_positions, other.tx_positions)
                and np.array_equal(self.rx_positions, other.rx_positions)
                and self.tx_pattern == other.tx_pattern and self.rx_pattern == other.rx_pattern
                and self.tx_sequence == other.tx_sequence)

    __hash__ = None  # type: ignore[assignment]

    @property
    def num_tx(self) -> int:
        return len(self.tx_positions)

    @property
    def num_rx(self) -> int:
        return len(self.rx_positions)

    @property
    def is_mimo(self) -> bool:
        """More than one transmitter takes part in the TDM sequence."""
        return len(set(self.tx_sequence)) > 1

    def chirp_tx(self, num_chirps: int) -> np.ndarray:
        """(num_chirps,) int: the transmitter index of every chirp of a frame."""
        seq = np.asarray(self.tx_sequence)
        return seq[np.arange(num_chirps) % len(seq)]

    def virtual_positions(self) -> np.ndarray:
        """TDM-MIMO virtual array, (len(tx_sequence) * n_rx, 3) [m].

        Row ``s * n_rx + a`` is ``tx[tx_sequence[s]] + rx[a]``: a far-field
        target gives the phase of a receiver at that position with a
        transmitter at the origin (the two-way path is |p - tx| + |p - rx|).
        """
        tx = self.tx_positions[np.asarray(self.tx_sequence)]
        return (tx[:, None, :] + self.rx_positions[None, :, :]).reshape(-1, 3)

    def to_dict(self) -> dict:
        return {"tx_positions": self.tx_positions.tolist(),
                "rx_positions": self.rx_positions.tolist(),
                "tx_pattern": vars(self.tx_pattern).copy(),
                "rx_pattern": vars(self.rx_pattern).copy(),
                "tx_sequence": list(self.tx_sequence)}


def ula_positions(num: int, spacing: float, axis: str = "x",
                  origin: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Uniform linear array, (num, 3) [m].

    ``axis`` "x" places elements to the right (azimuth array), "y" upwards
    (elevation array; +y is down in the optical frame, so elements go to -y).
    """
    n = V.integer("num", num, lo=1)
    d = V.positive("spacing", spacing, unit="m")
    step = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, -1.0, 0.0])}
    if axis not in step:
        raise ConfigError("axis", axis, "'x' (azimuth) or 'y' (elevation)")
    return np.asarray(origin, float) + np.arange(n)[:, None] * d * step[axis]


def l_shaped_positions(spacing: float) -> np.ndarray:
    """Three receivers in an L, (3, 3) [m]: RX1 right of the corner, RX2 above it, RX3 the corner.

    Follows the BGT60TR13C numbering as used by Infineon's angle examples:
    RX1/RX3 form the azimuth pair and RX2/RX3 the elevation pair.
    """
    d = V.positive("spacing", spacing, unit="m")
    return np.array([[d, 0.0, 0.0], [0.0, -d, 0.0], [0.0, 0.0, 0.0]])


def planar_positions(num_x: int, num_y: int, spacing_x: float,
                     spacing_y: float | None = None) -> np.ndarray:
    """2-D rectangular array, (num_x * num_y, 3) [m], row-major (elevation row, azimuth column)."""
    nx = V.integer("num_x", num_x, lo=1)
    ny = V.integer("num_y", num_y, lo=1)
    dx = V.positive("spacing_x", spacing_x, unit="m")
    dy = dx if spacing_y is None else V.positive("spacing_y", spacing_y, unit="m")
    jy, jx = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    return np.stack([jx.ravel() * dx, -jy.ravel() * dy, np.zeros(nx * ny)], axis=1)


def ula(num_rx: int, wavelength: float, *, num_tx: int = 1,
        pattern: ElementPattern | None = None) -> AntennaArray:
    """Receive ULA at lambda/2 with ``num_tx`` transmitters spaced ``num_rx * lambda/2`` (TDM-MIMO).

    With several transmitters the virtual array is a filled ULA of
    ``num_tx * num_rx`` elements at lambda/2.
    """
    lam = V.positive("wavelength", wavelength, unit="m")
    p = pattern or ElementPattern()
    rx = ula_positions(num_rx, lam / 2)
    tx = ula_positions(num_tx, num_rx * lam / 2) - np.array([0.0, 0.0, 0.0])
    # Keep the transmitters a few wavelengths left of the receivers, as on real boards.
    tx = tx + np.array([-2.0 * lam - (num_tx - 1) * num_rx * lam / 2, 0.0, 0.0])
    return AntennaArray(tx, rx, p, p)
