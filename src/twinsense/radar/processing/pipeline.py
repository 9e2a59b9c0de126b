"""The whole FMCW processing chain on one frame's raw cube.

    raw cube (rx, chirp, sample)
      -> DC removal (per chirp)            fft.remove_dc
      -> windowed range FFT                fft.range_fft          (rx, chirp, range_bin)
      -> TDM-MIMO demultiplex              mimo.demultiplex       (virtual, loop, range_bin)
      -> MTI (optional)                    fft.mti
      -> windowed Doppler FFT              fft.doppler_fft        (virtual, doppler_bin, range_bin)
      -> TDM Doppler phase compensation    mimo.compensate_doppler_phase
      -> non-coherent sum over channels    power map              (doppler_bin, range_bin)
      -> CFAR (2-D, or 1-D along range     cfar.cfar_2d / cfar_1d
         when there are too few Doppler bins)
      -> peak grouping                     peaks.group_peaks
      -> angle of arrival per detection    doa.estimate_direction_cosine
      -> point cloud (sensor, world)       detections.RadarPointCloud

All parameters are plain numbers and arrays in SI units, so the chain runs on
simulated cubes and on real recordings alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.radar.processing import fft as rfft
from twinsense.radar.processing import mimo
from twinsense.radar.processing.cfar import CFAR_METHODS, CfarResult, cfar_1d, cfar_2d
from twinsense.radar.processing.detections import RadarPointCloud
from twinsense.radar.processing.doa import DOA_METHODS, estimate_direction_cosine
from twinsense.radar.processing.peaks import GROUPING_METHODS, group_peaks, parabolic_offset
from twinsense.radar.processing.windows import WINDOWS


@dataclass(frozen=True)
class ProcessingSettings:
    """Choices of the processing chain (waveform parameters are passed separately).

    Attributes
    ----------
    range_window, doppler_window : str
        Names in :data:`~twinsense.radar.processing.windows.WINDOWS`.
    range_fft_size, doppler_fft_size : int or None
        FFT lengths (zero padding); None = number of samples / loops.
    remove_dc : bool
        Subtract each chirp's mean before the range FFT.
    mti : {"none", "mean", "two_pulse"}
        Static clutter removal along slow time.
    cfar : str
        Name in :data:`~twinsense.radar.processing.cfar.CFAR_METHODS`.
    cfar_guard, cfar_train : (int, int)
        Guard / training cells per side, (doppler, range).
    pfa : float
        Design false-alarm probability per cell.
    os_rank : int or None
        OS-CFAR order statistic (default 3/4 of the training cells).
    grouping : {"local_max", "cluster", "none"}
        Peak grouping rule.
    doa : str
        "auto" (monopulse for 2 elements, Bartlett otherwise) or a name
        in :data:`~twinsense.radar.processing.doa.DOA_METHODS`.
    min_range : float
        Detections nearer than this [m] are dropped (Tx-Rx leakage, DC).
    max_range : float or None
        Detections further than this [m] are dropped (None: none). A radar
        with a complex IF sets it, when it is None, to the range of its
        anti-alias filter's cutoff (:meth:`FMCWRadar.process_cube`): the
        bins beyond it also hold the negative beat frequencies next to DC,
        where the Tx-Rx leakage's window skirts wrap to (a still
        IWR6843 reported a point at its last bin, 11.1 m, 12 dB over the
        noise); TI's demo configurations keep their CFAR field of view
        below it as well.
    max_detections : int
        Keep at most this many detections (the strongest).
    compensate_tdm_doppler : bool
        Remove the TDM-MIMO Doppler phase before angle estimation.
    interpolate : bool
        Refine range and velocity by a parabola through the peak (in dB).
    """

    range_window: str = "hann"
    doppler_window: str = "hann"
    range_fft_size: int | None = None
    doppler_fft_size: int | None = None
    remove_dc: bool = True
    mti: str = "none"
    cfar: str = "ca"
    cfar_guard: tuple[int, int] = (1, 2)
    cfar_train: tuple[int, int] = (2, 8)
    pfa: float = 1e-4
    os_rank: int | None = None
    grouping: str = "local_max"
    doa: str = "auto"
    min_range: float = 0.0
    max_range: float | None = None
    max_detections: int = 128
    compensate_tdm_doppler: bool = True
    interpolate: bool = True

    def __post_init__(self) -> None:
        name = type(self).__name__
        for f in ("range_window", "doppler_window"):
            if getattr(self, f) not in WINDOWS:
                raise UnknownNameError(f"{name}.{f}", getattr(self, f), list(WINDOWS))
        for f in ("range_fft_size", "doppler_fft_size"):
            if getattr(self, f) is not None:
                V.integer(f"{name}.{f}", getattr(self, f), lo=1)
        V.choice(f"{name}.mti", self.mti, rfft.MTI_METHODS)
        if self.cfar not in CFAR_METHODS:
            raise UnknownNameError(f"{name}.cfar", self.cfar, list(CFAR_METHODS))
        for f in ("cfar_guard", "cfar_train"):
            v = getattr(self, f)
            if not isinstance(v, tuple) or len(v) != 2:
                raise ConfigError(f"{name}.{f}", v, "a pair (doppler, range) of integers")
            for i, axis in enumerate(("doppler", "range")):
                V.integer(f"{name}.{f}[{axis}]", v[i], lo=0 if f == "cfar_guard" else 1)
        for i, axis in enumerate(("doppler", "range")):
            if self.cfar_guard[i] >= self.cfar_train[i]:
                raise ConfigError(f"{name}.cfar_guard[{axis}]", self.cfar_guard[i],
                                  f"fewer guard cells than training cells "
                                  f"(cfar_train[{axis}] = {self.cfar_train[i]})")
        V.number(f"{name}.pfa", self.pfa, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
        if self.os_rank is not None:
            V.integer(f"{name}.os_rank", self.os_rank, lo=1)
        V.choice(f"{name}.grouping", self.grouping, GROUPING_METHODS)
        if self.doa != "auto" and self.doa not in DOA_METHODS:
            raise UnknownNameError(f"{name}.doa", self.doa, ["auto", *DOA_METHODS])
        V.non_negative(f"{name}.min_range", self.min_range, "m")
        if self.max_range is not None:
            V.positive(f"{name}.max_range", self.max_range, "m")
        V.integer(f"{name}.max_detections", self.max_detections, lo=0)


@dataclass(frozen=True, eq=False)
class ProcessingResult:
    """Everything the chain computed for one frame.

    Attributes
    ----------
    range_axis : (n_range,) float
        Range of each bin [m].
    velocity_axis : (n_doppler,) float
        Radial velocity of each (fftshifted) Doppler bin [m/s].
    range_doppler : (n_virtual, n_doppler, n_range) complex
        Range-Doppler spectra per (virtual) channel, TDM phase compensated.
    power : (n_doppler, n_range) float
        Mean over channels of ``|range_doppler|^2`` (the CFAR input).
    cfar : CfarResult
        Threshold and mask on ``power`` (1-D results broadcast to the map).
    detections : RadarPointCloud
        Grouped detections with angles, in sensor (and world) frames.
    virtual_positions : (n_virtual, 3) float
        Positions of the (virtual) channels [m], sensor frame.
    """

    range_axis: np.ndarray
    velocity_axis: np.ndarray
    range_doppler: np.ndarray
    power: np.ndarray
    cfar: CfarResult
    detections: RadarPointCloud
    virtual_positions: np.ndarray

    @property
    def range_profile(self) -> np.ndarray:
        """(n_range,) power averaged over channels and Doppler bins."""
        return self.power.mean(axis=0)


def _positions(field: str, value, n: int | None) -> np.ndarray:
    p = np.asarray(value, dtype=float)
    if p.ndim == 1:  # x coordinates of a ULA along the sensor's x axis
        p = np.column_stack([p, np.zeros_like(p), np.zeros_like(p)])
    p = V.array(field, p, (n, 3), "m")
    return p


def _line(positions: np.ndarray, along: int, across: int, tol: float) -> np.ndarray:
    """Indices of the largest group of elements sharing ``across`` with distinct ``along``."""
    best = np.zeros(0, dtype=int)
    keys = np.round(positions[:, across] / tol).astype(np.int64)
    for key in np.unique(keys):
        idx = np.flatnonzero(keys == key)
        # Overlapping virtual elements carry the same information: keep the first.
        _, first = np.unique(np.round(positions[idx, along] / tol), return_index=True)
        idx = idx[np.sort(first)]
        if len(idx) > len(best):
            best = idx
    return best if len(best) >= 2 else np.zeros(0, dtype=int)


def process_cube(cube: np.ndarray, *, sample_rate: float, slope: float,
                 carrier_frequency: float, chirp_repetition_time: float,
                 rx_positions, tx_positions=None, real_if: bool | None = None,
                 settings: ProcessingSettings | None = None, pose=None) -> ProcessingResult:
    """Run the processing chain on one frame.

    Parameters
    ----------
    cube : array, (rx, chirp, sample)
        Raw IF samples (ADC codes or volts; real for a real-IF device,
        complex I + jQ for an I/Q device). TDM-MIMO chirps in firing order.
    sample_rate : float
        ADC sample rate [Hz].
    slope : float
        Chirp slope S [Hz/s] during sampling.
    carrier_frequency : float
        Frequency at the middle of the sampled ramp [Hz] (sets the wavelength
        for Doppler and angle).
    chirp_repetition_time : float
        Time between consecutive chirps [s] (any transmitter).
    rx_positions : (n_rx, 3) or (n_rx,) float
        Receive antenna positions in the sensor frame [m]; a 1-D array gives
        x coordinates of a horizontal ULA.
    tx_positions : (n_tx, 3) or (n_tx,) float, optional
        Transmit antenna positions [m] for TDM-MIMO (default: one Tx at 0).
    real_if : bool, optional
        Real-IF input; default: True unless ``cube`` is complex.
    settings : ProcessingSettings, optional
        Chain choices (defaults: Hann windows, CA-CFAR 1e-4, auto DoA).
    pose : twinsense.scene.Pose, optional
        Sensor-to-world pose; adds world-frame points to the detections.
    """
    s = settings or ProcessingSettings()
    x = np.asarray(cube)
    if x.ndim != 3:
        raise ConfigError("cube", f"array of shape {x.shape}", "a (rx, chirp, sample) array")
    n_rx, n_chirp, n_samp = x.shape
    real_if = not np.iscomplexobj(x) if real_if is None else bool(real_if)
    rx = _positions("rx_positions", rx_positions, n_rx)
    tx = (np.zeros((1, 3)) if tx_positions is None
          else _positions("tx_positions", tx_positions, None))
    n_tx = len(tx)
    if n_chirp % n_tx:
        raise ConfigError("tx_positions", f"{n_tx} transmitters",
                          f"a number of transmitters dividing the chirp count ({n_chirp})")
    fc = V.positive("carrier_frequency", carrier_frequency, "Hz")
    t_c = V.positive("chirp_repetition_time", chirp_repetition_time, "s")
    lam = rfft.wavelength(fc)

    rd, power, n_rfft, n_loops = _range_doppler(x, s, real_if, n_tx)
    n_dfft = rd.shape[1]
    t_loop = n_tx * t_c
    r_axis = rfft.range_axis(power.shape[1], sample_rate=sample_rate, slope=slope, n_fft=n_rfft)
    v_axis = rfft.velocity_axis(n_dfft, chirp_repetition_time=t_loop, carrier_frequency=fc)
    limits = dict(
        max_range=rfft.max_range(sample_rate=sample_rate, slope=slope, real_if=real_if),
        max_velocity=rfft.max_velocity(chirp_repetition_time=t_loop, carrier_frequency=fc),
        range_resolution=rfft.range_resolution(sample_rate=sample_rate, slope=slope,
                                               n_samples=n_samp),
        velocity_resolution=rfft.velocity_resolution(n_loops, chirp_repetition_time=t_loop,
                                                     carrier_frequency=fc),
    )

    cf, d_idx, r_idx = _detect(power, r_axis, s)
    virt = mimo.virtual_array(tx, rx)
    if len(d_idx) == 0:
        return ProcessingResult(r_axis, v_axis, rd, power, cf,
                                _with_pose(RadarPointCloud.empty(**limits), pose), virt)
    p_det = power[d_idx, r_idx]
    rng, vel = r_axis[r_idx].copy(), v_axis[d_idx].copy()
    if s.interpolate:
        rng, vel = _refined(power, r_axis, v_axis, d_idx, r_idx, rng, vel)
    az, el = _angles(rd[:, d_idx, r_idx].T, virt, lam, s.doa)
    noise = cf.noise[d_idx, r_idx] if cf.noise.ndim == 2 else cf.noise[r_idx]
    cloud = RadarPointCloud.from_polar(
        range=rng, velocity=vel, azimuth=az, elevation=el,
        snr_db=10.0 * np.log10(p_det / np.maximum(noise, 1e-300)),
        power=p_det, range_bin=r_idx, doppler_bin=d_idx, pose=pose, **limits)
    return ProcessingResult(r_axis, v_axis, rd, power, cf, cloud, virt)


def _range_doppler(x: np.ndarray, s: ProcessingSettings, real_if: bool,
                   n_tx: int) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Raw cube (rx, chirp, sample) -> range-Doppler spectra (virtual, doppler_bin, range_bin),
    their mean power over channels (doppler_bin, range_bin), the range FFT length and the
    number of slow-time loops after MTI."""
    if s.remove_dc:
        x = rfft.remove_dc(x, axis=-1)
    n_rfft = s.range_fft_size or x.shape[-1]
    spec = rfft.range_fft(x, n_fft=n_rfft, window=s.range_window, real_if=real_if)
    if n_tx > 1:
        spec = mimo.demultiplex(spec, n_tx)
    spec = rfft.mti(spec, s.mti, axis=1)
    n_loops = spec.shape[1]
    if n_loops == 0:
        raise ConfigError("ProcessingSettings.mti", s.mti, "'none' or 'mean' for a single chirp")
    n_dfft = s.doppler_fft_size or n_loops
    rd = rfft.doppler_fft(spec, n_fft=n_dfft, window=s.doppler_window, axis=1)
    if n_tx > 1 and s.compensate_tdm_doppler:
        rd = mimo.compensate_doppler_phase(rd, n_tx)
    power = np.mean(rd.real ** 2 + rd.imag ** 2, axis=0)
    return rd, power, n_rfft, n_loops


def _detect(power: np.ndarray, r_axis: np.ndarray,
            s: ProcessingSettings) -> tuple[CfarResult, np.ndarray, np.ndarray]:
    """CFAR on the (doppler_bin, range_bin) power map, then peak grouping: the CFAR
    result and the (doppler, range) bin indices of at most ``max_detections`` peaks."""
    gd, gr = s.cfar_guard
    td, tr = s.cfar_train
    if power.shape[0] >= 2 * (gd + td) + 1:
        cf = cfar_2d(power, s.cfar, guard=s.cfar_guard, train=s.cfar_train, pfa=s.pfa,
                     rank=s.os_rank)
    else:
        # Too few Doppler bins for a 2-D window (static or short frames).
        cf = cfar_1d(power, s.cfar, guard=gr, train=tr, pfa=s.pfa, rank=s.os_rank, axis=-1)
    keep = r_axis >= s.min_range
    if s.max_range is not None:
        keep &= r_axis <= s.max_range
    mask = cf.mask & keep[None, :]
    d_idx, r_idx = group_peaks(power, mask, s.grouping)
    return cf, d_idx[: s.max_detections], r_idx[: s.max_detections]


def _refined(power, r_axis, v_axis, d_idx, r_idx, rng, vel) -> tuple[np.ndarray, np.ndarray]:
    """Range and velocity (n_det,) of the peaks refined by a parabola through the peak
    and its neighbours in dB (range: interior bins only; Doppler: periodic)."""
    db = 10.0 * np.log10(np.maximum(power, 1e-300))
    n_d, n_r = power.shape
    inner = (r_idx > 0) & (r_idx < n_r - 1)
    rl, rr = np.clip(r_idx - 1, 0, n_r - 1), np.clip(r_idx + 1, 0, n_r - 1)
    off_r = np.where(inner, parabolic_offset(db[d_idx, rl], db[d_idx, r_idx], db[d_idx, rr]), 0)
    rng = rng + off_r * (r_axis[1] - r_axis[0] if n_r > 1 else 0.0)
    if n_d > 2:
        dl, dr = (d_idx - 1) % n_d, (d_idx + 1) % n_d
        off_d = parabolic_offset(db[dl, r_idx], db[d_idx, r_idx], db[dr, r_idx])
        vel = vel + off_d * (v_axis[1] - v_axis[0])
    return rng, vel


def _angles(snap: np.ndarray, virt: np.ndarray, lam: float,
            doa: str) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth and elevation [rad] (n_det,) from the detections' snapshots (n_det, n_virtual):
    the largest row of the virtual array gives u_x, the largest column u_up."""
    tol = 1e-3 * lam
    row = _line(virt, along=0, across=1, tol=tol)
    col = _line(virt, along=1, across=0, tol=tol)
    u_x = np.zeros(len(snap))
    u_up = np.zeros(len(snap))
    if len(row):
        u_x = estimate_direction_cosine(snap[:, row], virt[row, 0], lam, _doa_name(doa, row))
    if len(col):
        # "Up" is -y in the optical sensor frame.
        u_up = estimate_direction_cosine(snap[:, col], -virt[col, 1], lam, _doa_name(doa, col))
    az = np.arctan2(u_x, np.sqrt(np.clip(1.0 - u_x ** 2 - u_up ** 2, 0.0, None)))
    el = np.arcsin(np.clip(u_up, -1.0, 1.0))
    return az, el


def _doa_name(name: str, idx: np.ndarray) -> str:
    if name == "auto":
        return "monopulse" if len(idx) == 2 else "bartlett"
    return name


def _with_pose(cloud: RadarPointCloud, pose) -> RadarPointCloud:
    return cloud if pose is None else cloud.in_world(pose)
