"""Configuration of an AMCW time-of-flight camera (PMD-style two-tap pixels).

Every physical parameter of the simulated device lives in one frozen
dataclass, :class:`ToFConfig`, validated when it is built: a bad value raises
:class:`~twinsense.errors.ConfigError` naming the field, the value and what
is allowed. SI units throughout; a field in another unit says so in its name.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from twinsense import validation as V
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError

#: Number of phase steps per modulation frequency (tau_i = i * pi / 2).
PHASE_STEPS = 4
#: Largest frequency ratio f_i / gcd(f_1, f_2) the dual-frequency unwrapper accepts.
MAX_UNWRAP_RATIO = 16
#: Royale's noise cut-off [m] and the modulation frequencies of the modes it was set for.
ROYALE_MAX_NOISE = 0.07
ROYALE_MAX_NOISE_FREQUENCIES = (80.32e6, 60.24e6)

_P = "ToFConfig"


@dataclass(frozen=True)
class ToFConfig:
    """All parameters of a simulated AMCW ToF camera.

    Optics
    ------
    width, height : int
        Sensor resolution [px].
    fov_deg : (2,) float or None
        Horizontal and vertical field of view, edge to edge [deg]. Give either
        this or ``intrinsics_px``.
    intrinsics_px : (4,) float or None
        Calibrated (fx, fy, cx, cy) [px], pixel centres at integer coordinates.
    distortion : (5,) float
        OpenCV (k1, k2, p1, p2, k3).
    supersample : int
        N: every pixel is rendered as N x N sub-pixel rays (1..8).
    f_number : float
        Lens f-number N = f/D; the collected irradiance scales with 1/(4 N^2).
    lens_transmission : float
        Transmission of lens and band-pass filter, 0..1.

    Modulation and timing
    ---------------------
    modulation_frequencies : tuple of 1 or 2 float
        Modulation frequencies [Hz], in capture order.
    gray_frame : bool
        The raw-frame sequence ends with one gray-value (intensity) frame, as
        the pmd devices' 5- and 9-frame modes do.
    exposure_time : float
        Integration time of each raw frame [s].
    readout_time : float
        Readout gap between consecutive raw frames [s].
    frame_rate : float
        Depth frames per second [Hz].

    Illumination
    ------------
    illumination_power : float
        Optical power emitted while the illumination is on [W].
    illumination_fwhm_deg : (2,) float
        Full width at half maximum of the Gaussian beam, horizontal and
        vertical [deg].
    wavelength : float
        Illumination wavelength [m].

    Pixel and read-out
    ------------------
    pixel_pitch : float
        Pixel pitch [m].
    fill_factor : float
        Light-sensitive share of the pixel area (micro-lenses included), 0..1.
    quantum_efficiency : float
        Electrons per photon at ``wavelength``, 0..1.
    demodulation_contrast : float
        c_d: share of the signal electrons that the two taps separate, 0..1.
    full_well : float
        Capacity of one tap [electrons].
    read_noise : float
        Read noise of one tap [electrons rms].
    dark_current : float
        Dark electrons per tap per second [e-/s].
    adc_bits : int
        ADC resolution (raw values 0 .. 2**bits - 1).
    adc_offset_dn : float
        Raw value of a zero tap difference [DN].
    electrons_per_dn : float
        Tap-difference electrons per raw digital number [e-/DN].
    raw_valid_range_dn : (2,) float
        Raw values outside this window mark the pixel saturated [DN].

    Scene light and material response
    ---------------------------------
    ambient_irradiance : float
        Unmodulated in-band irradiance on the scene (sunlight, lamps) [W/m^2].
    specular_exponent : float
        Phong exponent of the specular lobe of materials with ``nir_specular``.
    retroreflector_gain : float
        Radiance of a retro-reflector towards the source relative to a white
        Lambertian surface (pi * coefficient of retro-reflection).

    Effects and processing
    ----------------------
    crosstalk_sigma_px : float
        Standard deviation of the Gaussian optical/electrical cross-talk
        kernel applied to the correlation images [px]; 0 turns it off.
    noise : bool
        Shot, read and dark noise on (False: expected values only).
    quantization : bool
        Round tap differences to ADC digital numbers.
    min_amplitude_dn : float
        Pixels with a smaller amplitude are invalid (low signal) [DN].
    flying_pixel_filter : bool
        Royale-style flying-pixel filter on.
    flying_pixel_distance_near, flying_pixel_threshold_near : float
        The filter threshold [m] at and below this z-depth [m].
    flying_pixel_distance_far, flying_pixel_threshold_far : float
        The filter threshold [m] at and beyond this z-depth [m]; linear in between.
    flying_pixel_false_rate : float
        Share of the pixels of a flat, edge-free surface that the filter may
        remove for their own noise; the threshold is raised above the
        Royale ramp where the pixels' noise needs it (see
        :func:`~twinsense.tof.filters.flying_pixel_mask`).
    noise_filter : bool
        Drop pixels whose estimated depth noise exceeds :attr:`noise_cutoff`.
    max_noise : float or None
        Noise cut-off [m]; None: Royale's 0.07 m carried over to this
        camera's modulation frequencies at the same phase noise (see
        :attr:`noise_cutoff`).
    multipath : bool
        Add one diffuse indirect bounce (virtual point lights).
    multipath_vpl_grid : (2,) int
        Virtual point lights along image x and y.
    multipath_stride : int
        The indirect light is gathered every ``stride`` pixels and interpolated.
    multipath_visibility : bool
        Shadow rays between light and receiving points (False: all mutually visible).
    motion_artifacts : bool
        Render every raw frame at its own capture time.
    """

    # optics
    width: int = 224
    height: int = 171
    fov_deg: tuple[float, float] | None = (62.0, 45.0)
    intrinsics_px: tuple[float, float, float, float] | None = None
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    supersample: int = 2
    f_number: float = 1.0
    lens_transmission: float = 0.9
    # modulation and timing
    modulation_frequencies: tuple[float, ...] = (80.32e6, 60.24e6)
    gray_frame: bool = True
    exposure_time: float = 450e-6
    readout_time: float = 1.0e-3
    frame_rate: float = 25.0
    # illumination
    illumination_power: float = 0.8
    illumination_fwhm_deg: tuple[float, float] = (80.0, 60.0)
    wavelength: float = 850e-9
    # pixel and read-out
    pixel_pitch: float = 17.5e-6
    fill_factor: float = 0.8
    quantum_efficiency: float = 0.35
    demodulation_contrast: float = 0.75
    full_well: float = 100_000.0
    read_noise: float = 20.0
    dark_current: float = 1000.0
    adc_bits: int = 12
    adc_offset_dn: float = 2048.0
    electrons_per_dn: float = 25.0
    raw_valid_range_dn: tuple[float, float] = (400.0, 3750.0)
    # scene light and materials
    ambient_irradiance: float = 0.05
    specular_exponent: float = 30.0
    retroreflector_gain: float = 300.0
    # effects and processing
    crosstalk_sigma_px: float = 0.6
    noise: bool = True
    quantization: bool = True
    min_amplitude_dn: float = 3.0
    flying_pixel_filter: bool = True
    flying_pixel_distance_near: float = 1.0
    flying_pixel_threshold_near: float = 0.018
    flying_pixel_distance_far: float = 4.5
    flying_pixel_threshold_far: float = 0.14
    flying_pixel_false_rate: float = 1e-3
    noise_filter: bool = True
    max_noise: float | None = None
    multipath: bool = False
    multipath_vpl_grid: tuple[int, int] = (24, 18)
    multipath_stride: int = 2
    multipath_visibility: bool = True
    motion_artifacts: bool = False

    def __post_init__(self) -> None:
        self._check_optics()
        self._check_modulation()
        self._check_timing()
        self._check_illumination()
        self._check_pixel()
        self._check_scene_light()
        self._check_processing()

    def _check_optics(self) -> None:
        p = _P
        V.integer(f"{p}.width", self.width, lo=1, hi=10_000)
        V.integer(f"{p}.height", self.height, lo=1, hi=10_000)
        if (self.fov_deg is None) == (self.intrinsics_px is None):
            raise ConfigError(f"{p}.fov_deg / {p}.intrinsics_px",
                              (self.fov_deg, self.intrinsics_px),
                              "exactly one of them set (the other None)")
        if self.fov_deg is not None:
            fov = V.vector(f"{p}.fov_deg", self.fov_deg, 2, "deg")
            for name, v in zip(("horizontal", "vertical"), fov):
                V.number(f"{p}.fov_deg ({name})", float(v), lo=0, hi=170, lo_open=True, unit="deg")
            self._set("fov_deg", tuple(float(x) for x in fov))
        else:
            k = V.vector(f"{p}.intrinsics_px", self.intrinsics_px, 4, "px")
            if k[0] <= 0 or k[1] <= 0:
                raise ConfigError(f"{p}.intrinsics_px", self.intrinsics_px,
                                  "(fx, fy, cx, cy) with fx > 0 and fy > 0 [px]")
            self._set("intrinsics_px", tuple(float(x) for x in k))
        dist = V.vector(f"{p}.distortion", self.distortion, 5)
        self._set("distortion", tuple(float(x) for x in dist))
        V.integer(f"{p}.supersample", self.supersample, lo=1, hi=8)
        V.number(f"{p}.f_number", self.f_number, lo=0.5, hi=64)
        V.number(f"{p}.lens_transmission", self.lens_transmission, lo=0, hi=1, lo_open=True)

    def _check_modulation(self) -> None:
        p = _P
        freqs = self.modulation_frequencies
        if isinstance(freqs, (int, float)) and not isinstance(freqs, bool):
            freqs = (freqs,)
        try:
            freqs = tuple(freqs)
        except TypeError:
            raise ConfigError(f"{p}.modulation_frequencies", self.modulation_frequencies,
                              "1 or 2 frequencies [Hz]") from None
        if len(freqs) not in (1, 2):
            raise ConfigError(f"{p}.modulation_frequencies", self.modulation_frequencies,
                              "1 or 2 frequencies [Hz]")
        freqs = tuple(V.number(f"{p}.modulation_frequencies[{i}]", f, lo=1e3, hi=2e9, unit="Hz")
                      for i, f in enumerate(freqs))
        self._set("modulation_frequencies", freqs)
        if len(freqs) == 2:
            g = _gcd_hz(*freqs)
            ratios = [round(f) // g for f in freqs]
            if freqs[0] == freqs[1] or max(ratios) > MAX_UNWRAP_RATIO:
                raise ConfigError(
                    f"{p}.modulation_frequencies", freqs,
                    f"two different frequencies whose ratio to their greatest common divisor "
                    f"is at most {MAX_UNWRAP_RATIO} (e.g. 80.32e6 and 60.24e6: 4 and 3)")

    def _check_timing(self) -> None:
        p = _P
        _bool(f"{p}.gray_frame", self.gray_frame)
        V.number(f"{p}.exposure_time", self.exposure_time, lo=0, hi=1, lo_open=True, unit="s")
        V.number(f"{p}.readout_time", self.readout_time, lo=0, hi=1, unit="s")
        V.number(f"{p}.frame_rate", self.frame_rate, lo=0, hi=10_000, lo_open=True, unit="Hz")
        if self.raw_sequence_time > 1.0 / self.frame_rate * (1 + 1e-9):
            raise ConfigError(
                f"{p}.frame_rate", self.frame_rate,
                f"at most 1 / (raw frames x (exposure_time + readout_time)) = "
                f"{1.0 / self.raw_sequence_time:.4g} Hz for {self.n_raw_frames} raw frames")

    def _check_illumination(self) -> None:
        p = _P
        V.number(f"{p}.illumination_power", self.illumination_power, lo=0, unit="W")
        beam = V.vector(f"{p}.illumination_fwhm_deg", self.illumination_fwhm_deg, 2, "deg")
        for v in beam:
            V.number(f"{p}.illumination_fwhm_deg", float(v), lo=1, hi=170, unit="deg")
        self._set("illumination_fwhm_deg", tuple(float(x) for x in beam))
        V.number(f"{p}.wavelength", self.wavelength, lo=200e-9, hi=20e-6, unit="m")

    def _check_pixel(self) -> None:
        p = _P
        V.number(f"{p}.pixel_pitch", self.pixel_pitch, lo=0.1e-6, hi=1e-3, unit="m")
        V.number(f"{p}.fill_factor", self.fill_factor, lo=0, hi=1, lo_open=True)
        V.number(f"{p}.quantum_efficiency", self.quantum_efficiency, lo=0, hi=1, lo_open=True)
        V.number(f"{p}.demodulation_contrast", self.demodulation_contrast, lo=0, hi=1, lo_open=True)
        V.number(f"{p}.full_well", self.full_well, lo=1, unit="electrons")
        V.non_negative(f"{p}.read_noise", self.read_noise, "electrons rms")
        V.non_negative(f"{p}.dark_current", self.dark_current, "electrons/s")
        V.integer(f"{p}.adc_bits", self.adc_bits, lo=4, hi=16)
        full = 2 ** self.adc_bits - 1
        V.number(f"{p}.adc_offset_dn", self.adc_offset_dn, lo=0, hi=full, unit="DN")
        V.positive(f"{p}.electrons_per_dn", self.electrons_per_dn, "electrons/DN")
        win = V.vector(f"{p}.raw_valid_range_dn", self.raw_valid_range_dn, 2, "DN")
        if not 0 <= win[0] < self.adc_offset_dn < win[1] <= full:
            raise ConfigError(f"{p}.raw_valid_range_dn", self.raw_valid_range_dn,
                              f"(low, high) with 0 <= low < adc_offset_dn ({self.adc_offset_dn:g}) "
                              f"< high <= {full} [DN]")
        self._set("raw_valid_range_dn", (float(win[0]), float(win[1])))

    def _check_scene_light(self) -> None:
        p = _P
        V.non_negative(f"{p}.ambient_irradiance", self.ambient_irradiance, "W/m^2")
        V.number(f"{p}.specular_exponent", self.specular_exponent, lo=1, hi=10_000)
        V.number(f"{p}.retroreflector_gain", self.retroreflector_gain, lo=1, hi=1e6)

    def _check_processing(self) -> None:
        p = _P
        V.number(f"{p}.crosstalk_sigma_px", self.crosstalk_sigma_px, lo=0, hi=20, unit="px")
        for flag in ("noise", "quantization", "flying_pixel_filter", "noise_filter", "multipath",
                     "multipath_visibility", "motion_artifacts"):
            _bool(f"{p}.{flag}", getattr(self, flag))
        V.non_negative(f"{p}.min_amplitude_dn", self.min_amplitude_dn, "DN")
        zn = V.positive(f"{p}.flying_pixel_distance_near", self.flying_pixel_distance_near, "m")
        V.positive(f"{p}.flying_pixel_threshold_near", self.flying_pixel_threshold_near, "m")
        V.number(f"{p}.flying_pixel_distance_far", self.flying_pixel_distance_far, lo=zn,
                 lo_open=True, unit="m (> flying_pixel_distance_near)")
        V.positive(f"{p}.flying_pixel_threshold_far", self.flying_pixel_threshold_far, "m")
        V.number(f"{p}.flying_pixel_false_rate", self.flying_pixel_false_rate, lo=1e-9, hi=0.1)
        if self.max_noise is not None:
            V.positive(f"{p}.max_noise", self.max_noise, "m (or None: derived from the modulation)")
        grid = self.multipath_vpl_grid
        if (not isinstance(grid, (tuple, list)) or len(grid) != 2
                or not all(isinstance(g, (int, np.integer)) and not isinstance(g, bool) and 1 <= g <= 256
                           for g in grid)):
            raise ConfigError(f"{p}.multipath_vpl_grid", grid, "two integers in 1..256 (x, y)")
        self._set("multipath_vpl_grid", (int(grid[0]), int(grid[1])))
        V.integer(f"{p}.multipath_stride", self.multipath_stride, lo=1, hi=16)

    def _set(self, name: str, value) -> None:
        object.__setattr__(self, name, value)

    # --- derived quantities -------------------------------------------------

    @property
    def n_frequencies(self) -> int:
        return len(self.modulation_frequencies)

    @property
    def n_raw_frames(self) -> int:
        """Raw frames per depth frame: 4 phase steps per frequency, plus the gray frame."""
        return PHASE_STEPS * self.n_frequencies + int(self.gray_frame)

    @property
    def raw_sequence_time(self) -> float:
        """Time the raw-frame sequence takes [s]."""
        return self.n_raw_frames * (self.exposure_time + self.readout_time)

    def raw_frame_times(self, t0: float) -> np.ndarray:
        """Start times (n_raw_frames,) [s] of the raw frames of the depth frame starting at ``t0``.

        t_i = t0 + i (exposure_time + readout_time); frequency-major, then phase
        step, then the gray frame last.
        """
        return t0 + np.arange(self.n_raw_frames) * (self.exposure_time + self.readout_time)

    @property
    def unambiguous_range(self) -> float:
        """Largest distance measured without wrapping [m]: c / (2 gcd(f))."""
        f = self.modulation_frequencies
        g = f[0] if len(f) == 1 else float(_gcd_hz(*f))
        return SPEED_OF_LIGHT / (2.0 * g)

    @property
    def camera_intrinsics(self) -> tuple[float, float, float, float]:
        """(fx, fy, cx, cy) [px], from ``intrinsics_px`` or from ``fov_deg``."""
        if self.intrinsics_px is not None:
            return self.intrinsics_px
        hfov, vfov = (math.radians(a) for a in self.fov_deg)
        fx = 0.5 * self.width / math.tan(hfov / 2)
        fy = 0.5 * self.height / math.tan(vfov / 2)
        return (fx, fy, (self.width - 1) / 2, (self.height - 1) / 2)

    @property
    def effective_frequency(self) -> float:
        """Frequency [Hz] of a single-frequency camera with the same depth noise: sqrt(sum f_k^2).

        Every frequency sees the same phase noise sigma_phi (same exposure, same
        amplitude); its distance noise is c sigma_phi / (4 pi f_k), and the
        inverse-variance weights w_k = f_k^2 / sum f^2 of the unwrapper give
        sigma_d^2 = sum w_k^2 (c sigma_phi / (4 pi f_k))^2 = (c sigma_phi / 4 pi)^2 / sum f_k^2.
        """
        return math.sqrt(sum(f * f for f in self.modulation_frequencies))

    @property
    def noise_cutoff(self) -> float:
        """Distance noise [m] above which the noise filter drops a pixel.

        ``max_noise`` when set. Otherwise Royale's 0.07 m for the pico
        flexx's 80.32 + 60.24 MHz modes (effective frequency 100.4 MHz), a
        phase-noise (i.e. signal-to-noise) limit of
        sigma_phi = 0.07 m x 4 pi f_eff / c = 0.295 rad, carried over to this
        camera's effective frequency: the same confidence is a larger
        distance noise at a lower frequency (0.117 m at 60.24 MHz, 0.351 m at
        20 MHz).
        """
        if self.max_noise is not None:
            return self.max_noise
        royale = math.sqrt(sum(f * f for f in ROYALE_MAX_NOISE_FREQUENCIES))
        return ROYALE_MAX_NOISE * royale / self.effective_frequency

    def flying_pixel_threshold(self, z: np.ndarray) -> np.ndarray:
        """Flying-pixel threshold [m] at z-depth ``z`` [m] (linear between the near and far points)."""
        return np.interp(z, (self.flying_pixel_distance_near, self.flying_pixel_distance_far),
                         (self.flying_pixel_threshold_near, self.flying_pixel_threshold_far))

    def replaced(self, **changes) -> ToFConfig:
        """A validated copy with ``changes`` applied."""
        unknown = sorted(set(changes) - set(self.__dataclass_fields__))
        if unknown:
            from twinsense.errors import UnknownNameError

            raise UnknownNameError("ToFConfig field", unknown[0], list(self.__dataclass_fields__))
        return replace(self, **changes)

    def to_dict(self) -> dict:
        """JSON-able dict of every field."""
        d = asdict(self)
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()}


def _gcd_hz(f1: float, f2: float) -> int:
    """Greatest common divisor of two frequencies rounded to whole hertz [Hz]."""
    return math.gcd(round(f1), round(f2))


def _bool(field: str, value) -> None:
    if not isinstance(value, (bool, np.bool_)):
        raise ConfigError(field, value, "true or false")
