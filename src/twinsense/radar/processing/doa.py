"""Direction of arrival along one array axis.

Signal model: an element at position ``p`` [m] along the array axis sees a
far-field target with the phase ``-2 pi p u / lambda``, where ``u = sin(theta)``
is the direction cosine towards the positive axis. This is the phase of the
IF model ``2 pi f_c tau`` (PHYSICS.md) with the path shortened by ``p u`` (the
range-FFT bin keeps ``exp(+j phase)``, see :mod:`.fft`). The steering vector is
``a(u) = exp(-j 2 pi p u / lambda)``.

For the sensor frame (x right, y down, z forward) an array along +x measures
``u_x = cos(el) sin(az)`` and an array along "up" (positions ``-y``) measures
``sin(el)``; :mod:`.pipeline` combines the two.

Methods (registry :data:`DOA_METHODS`), each ``(snapshots, positions,
wavelength, n_sources, grid) -> u (n,)``:

- ``monopulse``: phase difference of neighbouring elements of a uniform
  array (two elements: the classic 2-Rx case), ``u = -lambda dphi / (2 pi d)``;
  unambiguous for ``d <= lambda / 2``.
- ``fft``: zero-padded spatial FFT; uniform arrays only.
- ``bartlett``: delay-and-sum spectrum ``a^H R a`` on a grid (any geometry).
- ``capon``: MVDR spectrum ``1 / (a^H R^-1 a)`` with diagonal loading.
- ``music``: ``1 / |E_n^H a|^2`` with the noise subspace ``E_n`` of ``R``
  (Schmidt 1986).

Grid methods refine the best grid point by a parabola through the spectrum in dB.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.radar.processing.peaks import parabolic_offset

#: Default search grid of direction cosines u = sin(theta).
DEFAULT_GRID = np.linspace(-1.0, 1.0, 401)

# Relative diagonal loading for Capon: keeps R invertible with a single
# snapshot and bounds the white-noise gain; 1e-2 of the mean element power
# is the customary robust choice (Van Trees, Optimum Array Processing, 6.6.4).
CAPON_LOADING = 1e-2


def steering_matrix(positions: np.ndarray, wavelength: float, grid: np.ndarray) -> np.ndarray:
    """Steering vectors, (n_grid, n_ant): ``exp(-j 2 pi p u / lambda)``."""
    p = np.asarray(positions, dtype=float)
    return np.exp(-2j * np.pi / wavelength * np.outer(np.asarray(grid, dtype=float), p))


def _snapshots(x: np.ndarray, n_ant: int) -> np.ndarray:
    """As (n_target, n_ant, n_snapshot)."""
    x = np.asarray(x)
    if x.ndim == 1:
        x = x[None, :, None]
    elif x.ndim == 2:
        x = x[:, :, None]
    if x.ndim != 3 or x.shape[1] != n_ant:
        raise ConfigError("snapshots", f"array of shape {np.shape(x)}",
                          f"(n_ant,), (n, n_ant) or (n, n_ant, n_snapshot) with n_ant = {n_ant}")
    return x.astype(complex)


def _covariance(x: np.ndarray) -> np.ndarray:
    return np.einsum("kas,kbs->kab", x, x.conj()) / x.shape[2]


def _peak(spec_db: np.ndarray, grid: np.ndarray) -> np.ndarray:
    i = np.argmax(spec_db, axis=1)
    inner = np.clip(i, 1, len(grid) - 2)
    rows = np.arange(spec_db.shape[0])
    off = parabolic_offset(spec_db[rows, inner - 1], spec_db[rows, inner], spec_db[rows, inner + 1])
    off = np.where(i == inner, off, 0.0)
    step = grid[1] - grid[0]
    return np.clip(grid[i] + off * step, -1.0, 1.0)


def spectrum(snapshots: np.ndarray, positions: np.ndarray, wavelength: float,
             method: str = "bartlett", *, n_sources: int = 1,
             grid: np.ndarray = DEFAULT_GRID) -> np.ndarray:
    """Angular spectrum (linear power) of a grid method, (n_target, n_grid).

    ``snapshots``: (n_ant,), (n_target, n_ant) or (n_target, n_ant, n_snapshot).
    """
    p = np.asarray(positions, dtype=float)
    x = _snapshots(snapshots, len(p))
    a = steering_matrix(p, wavelength, grid)
    r = _covariance(x)
    if method == "bartlett":
        return np.real(np.einsum("ga,kab,gb->kg", a.conj(), r, a)) / len(p)
    if method == "capon":
        load = CAPON_LOADING * np.real(np.trace(r, axis1=1, axis2=2)) / len(p)
        r = r + (load[:, None, None] + 1e-300) * np.eye(len(p))
        ri = np.linalg.inv(r)
        return 1.0 / np.maximum(np.real(np.einsum("ga,kab,gb->kg", a.conj(), ri, a)), 1e-300)
    if method == "music":
        if not 1 <= n_sources < len(p):
            raise ConfigError("n_sources", n_sources, f"an integer in [1, {len(p) - 1}]")
        _, vecs = np.linalg.eigh(r)  # ascending eigenvalues
        en = vecs[:, :, : len(p) - n_sources]
        proj = np.einsum("ga,kan->kgn", a.conj(), en)
        return 1.0 / np.maximum(np.sum(np.abs(proj) ** 2, axis=2), 1e-300)
    raise ConfigError("method", method, "a grid method: bartlett, capon or music")


def _grid_method(name: str) -> Callable:
    def estimate(snapshots, positions, wavelength, n_sources=1, grid=DEFAULT_GRID):
        s = spectrum(snapshots, positions, wavelength, name, n_sources=n_sources, grid=grid)
        return _peak(10.0 * np.log10(np.maximum(s, 1e-300)), grid)

    estimate.__doc__ = f"{name} estimate of u = sin(theta), (n_target,)."
    return estimate


def _uniform_order(p: np.ndarray, method: str) -> tuple[np.ndarray, float]:
    """Element order along the axis and the spacing of a uniform linear array."""
    order = np.argsort(p)
    d = np.diff(p[order])
    if len(p) < 2 or d[0] <= 0 or np.ptp(d) > 1e-6 * d[0]:
        raise ConfigError("positions", p.tolist(),
                          f"a uniform linear array of >= 2 distinct elements for {method}")
    return order, float(d[0])


def monopulse(snapshots, positions, wavelength, n_sources=1, grid=DEFAULT_GRID) -> np.ndarray:
    """Phase-difference (monopulse) estimate, u = -lambda dphi / (2 pi d), (n_target,).

    Two elements: their phase difference. A uniform array of more elements:
    the phase of the summed products of neighbours, ``sum_n x_{n+1} x_n^*``
    (Kay's weighted phase-difference estimator), which reduces to the
    two-element case. Unambiguous for spacing ``d <= lambda / 2``.
    """
    p = np.asarray(positions, dtype=float)
    order, d = _uniform_order(p, "monopulse")
    x = _snapshots(snapshots, len(p))[:, order, :]
    # Summing the products over pairs and snapshots before taking the angle
    # is the maximum-likelihood phase step for one source in white noise.
    dphi = np.angle(np.sum(x[:, 1:, :] * x[:, :-1, :].conj(), axis=(1, 2)))
    return np.clip(-wavelength * dphi / (2.0 * np.pi * d), -1.0, 1.0)


def fft_method(snapshots, positions, wavelength, n_sources=1, grid=DEFAULT_GRID,
               n_fft: int = 256) -> np.ndarray:
    """Zero-padded spatial FFT of a uniform linear array, (n_target,).

    With spacing d, FFT bin k (frequency k / n_fft cycles per element, taken
    in [-1/2, 1/2)) corresponds to ``-2 pi d u / lambda = 2 pi k / n_fft``.
    """
    p = np.asarray(positions, dtype=float)
    order, d = _uniform_order(p, "the fft method")
    x = _snapshots(snapshots, len(p))[:, order, :]
    spec = np.sum(np.abs(np.fft.fftshift(np.fft.fft(x, n=n_fft, axis=1), axes=1)) ** 2, axis=2)
    freq = (np.arange(n_fft) - n_fft // 2) / n_fft
    u_axis = -freq * wavelength / d
    sdb = 10.0 * np.log10(np.maximum(spec, 1e-300))
    i = np.argmax(sdb, axis=1)
    rows = np.arange(len(i))
    off = parabolic_offset(sdb[rows, (i - 1) % n_fft], sdb[rows, i], sdb[rows, (i + 1) % n_fft])
    return np.clip(u_axis[i] - off * wavelength / (d * n_fft), -1.0, 1.0)


#: name -> estimator ``(snapshots, positions, wavelength, n_sources, grid) -> u (n,)``.
DOA_METHODS: dict[str, Callable[..., np.ndarray]] = {
    "monopulse": monopulse,
    "fft": fft_method,
    "bartlett": _grid_method("bartlett"),
    "capon": _grid_method("capon"),
    "music": _grid_method("music"),
}


def estimate_direction_cosine(snapshots: np.ndarray, positions: np.ndarray, wavelength: float,
                              method: str = "bartlett", *, n_sources: int = 1,
                              grid: np.ndarray = DEFAULT_GRID) -> np.ndarray:
    """Direction cosine ``u = sin(theta)`` per target, (n_target,).

    Parameters
    ----------
    snapshots : complex array, (n_ant,), (n_target, n_ant) or (n_target, n_ant, n_snapshot)
        Element signals, e.g. the range-Doppler cell of each detection.
    positions : (n_ant,) float
        Element positions along the array axis [m].
    wavelength : float
        Carrier wavelength [m].
    method : str
        Key of :data:`DOA_METHODS`.
    n_sources : int
        Signal-subspace dimension (MUSIC).
    grid : (n_grid,) float
        Search grid of u values in [-1, 1] (grid methods).
    """
    if method not in DOA_METHODS:
        raise UnknownNameError("doa method", method, list(DOA_METHODS))
    V.positive("wavelength", wavelength, "m")
    V.integer("n_sources", n_sources, lo=1)
    return DOA_METHODS[method](snapshots, positions, wavelength, n_sources, grid)


def estimate_angle(snapshots: np.ndarray, positions: np.ndarray, wavelength: float,
                   method: str = "bartlett", **kwargs) -> np.ndarray:
    """Angle ``theta = arcsin(u)`` [rad] from the array normal towards +axis, (n_target,)."""
    return np.arcsin(estimate_direction_cosine(snapshots, positions, wavelength, method, **kwargs))
