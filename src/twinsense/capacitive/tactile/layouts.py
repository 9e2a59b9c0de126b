"""Tactile layer stacks: Tx and Rx electrode layers around a soft dielectric.

Skin frame: x, y in the skin plane, z up (the outward normal), the bottom of
the stack at z = 0 and the top surface at z = ``total_thickness``. From the
bottom up:

- an optional ground/shield plane at z = 0 (the robot link's metal, or a
  shield layer of the flex PCB);
- a rigid carrier (flex PCB, polyimide) of thickness ``base.thickness``;
- the Tx layer at ``z_tx`` (rows along x, or one common plane under pads);
- the soft dielectric (silicone), the layer that the contact compresses;
- the Rx layer at ``z_rx`` (columns along y, or one pad per taxel);
- an optional soft cover on top.

Two arrangements: ``"crossing"`` (rows x columns: every Tx row crosses every
Rx column, taxel (i, j) is the crossing of row i and column j, read in
mutual mode or as row/column self capacitances) and ``"pads"`` (one Rx pad
per taxel over a common Tx plane: every taxel has its own channel).
Electrodes are zero-thickness conductors lying on mesh node planes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twinsense import validation as v
from twinsense.errors import ConfigError

__all__ = ["ARRANGEMENTS", "StackLayer", "TactileLayout"]

ARRANGEMENTS = ("crossing", "pads")


@dataclass(frozen=True)
class StackLayer:
    """One layer of the stack.

    Attributes
    ----------
    thickness : float [m]
    permittivity : float, relative permittivity (> 0).
    material : str or ElasticMaterial, optional
        Elastic material (a :mod:`twinsense.capacitive.mechanics` preset name
        or an ``ElasticMaterial``); None for a rigid layer.
    """

    thickness: float
    permittivity: float
    material: object = None

    def __post_init__(self) -> None:
        v.positive("StackLayer.thickness", self.thickness, "m")
        v.number("StackLayer.permittivity", self.permittivity, lo=1.0)
        m = self.material
        if m is not None and not isinstance(m, str) and not (hasattr(m, "young") and hasattr(m, "poisson")):
            raise ConfigError("StackLayer.material", m, "None, a mechanics preset name or an ElasticMaterial")


@dataclass(frozen=True)
class TactileLayout:
    """A taxel array on a layer stack (see the module notes for the frame).

    Attributes
    ----------
    name : str
    arrangement : {"crossing", "pads"}
    rows, cols : int, taxels along y (rows) and x (columns).
    pitch : float, taxel pitch [m] (both directions).
    tx_width : float, width of a Tx row [m] ("crossing"; "pads" uses a plane).
    rx_width : float, width of an Rx column, or side of a square pad [m].
    dielectric : StackLayer, the soft layer between Tx and Rx.
    cover : StackLayer or None, the soft layer above Rx.
    base : StackLayer, the rigid carrier under Tx.
    shield : bool, a grounded plane at z = 0 under the whole stack.
    edge : float, skin beyond the outermost taxel edge on every side [m].
    """

    name: str
    arrangement: str
    rows: int
    cols: int
    pitch: float
    tx_width: float
    rx_width: float
    dielectric: StackLayer
    cover: StackLayer | None = None
    base: StackLayer = StackLayer(0.2e-3, 3.4)
    shield: bool = True
    edge: float = 2e-3

    def __post_init__(self) -> None:
        v.choice("TactileLayout.arrangement", self.arrangement, ARRANGEMENTS)
        v.integer("TactileLayout.rows", self.rows, lo=1, hi=64)
        v.integer("TactileLayout.cols", self.cols, lo=1, hi=64)
        v.positive("TactileLayout.pitch", self.pitch, "m")
        for f in ("tx_width", "rx_width"):
            w = v.positive(f"TactileLayout.{f}", getattr(self, f), "m")
            if w >= self.pitch:
                raise ConfigError(f"TactileLayout.{f}", w,
                                  f"a width < the pitch {self.pitch} m (a gap between electrodes)")
        for f in ("dielectric", "base"):
            if not isinstance(getattr(self, f), StackLayer):
                raise ConfigError(f"TactileLayout.{f}", getattr(self, f), "a StackLayer")
        if self.dielectric.material is None:
            raise ConfigError("TactileLayout.dielectric.material", None, "an elastic material (it is compressed)")
        if self.cover is not None and not isinstance(self.cover, StackLayer):
            raise ConfigError("TactileLayout.cover", self.cover, "a StackLayer or None")
        if self.cover is not None and self.cover.material is None:
            raise ConfigError("TactileLayout.cover.material", None, "an elastic material (it is compressed)")
        v.non_negative("TactileLayout.edge", self.edge, "m")

    # -- heights --------------------------------------------------------------
    @property
    def z_tx(self) -> float:
        """Height of the Tx layer [m]."""
        return self.base.thickness

    @property
    def z_rx(self) -> float:
        """Height of the Rx layer [m]."""
        return self.base.thickness + self.dielectric.thickness

    @property
    def total_thickness(self) -> float:
        """Height of the top surface [m]."""
        return self.z_rx + (self.cover.thickness if self.cover is not None else 0.0)

    # -- electrodes -------------------------------------------------------------
    @property
    def x_centers(self) -> np.ndarray:
        """(cols,) taxel centres along x [m]."""
        return (np.arange(self.cols) - 0.5 * (self.cols - 1)) * self.pitch

    @property
    def y_centers(self) -> np.ndarray:
        """(rows,) taxel centres along y [m]."""
        return (np.arange(self.rows) - 0.5 * (self.rows - 1)) * self.pitch

    @property
    def half_extent(self) -> tuple[float, float]:
        """Half sizes (x, y) of the skin [m]: the taxel array plus ``edge``."""
        return 0.5 * self.cols * self.pitch + self.edge, 0.5 * self.rows * self.pitch + self.edge

    @property
    def taxel_area(self) -> float:
        """Area one taxel stands for [m^2] (pitch squared)."""
        return self.pitch**2

    @property
    def tx_names(self) -> tuple[str, ...]:
        if self.arrangement == "pads":
            return ("tx",)
        return tuple(f"row{i}" for i in range(self.rows))

    @property
    def rx_names(self) -> tuple[str, ...]:
        if self.arrangement == "pads":
            return tuple(f"pad{i}_{j}" for i in range(self.rows) for j in range(self.cols))
        return tuple(f"col{j}" for j in range(self.cols))

    @property
    def electrode_names(self) -> tuple[str, ...]:
        """Terminal order of the Maxwell matrix: Tx electrodes, then Rx."""
        return self.tx_names + self.rx_names

    def taxel_terminals(self) -> tuple[np.ndarray, np.ndarray]:
        """((rows, cols) Tx terminal index, (rows, cols) Rx terminal index) of every taxel."""
        i, j = np.meshgrid(np.arange(self.rows), np.arange(self.cols), indexing="ij")
        ntx = len(self.tx_names)
        if self.arrangement == "pads":
            return np.zeros_like(i), ntx + i * self.cols + j
        return i, ntx + j

    def x_features(self) -> list[float]:
        """Grid lines along x the mesh must contain (electrode edges, skin edge) [m]."""
        hx, _ = self.half_extent
        w = self.rx_width / 2
        out = [-hx, hx, -0.5 * self.cols * self.pitch, 0.5 * self.cols * self.pitch]
        for x in self.x_centers:
            out += [x - w, x + w]
        return out

    def y_features(self) -> list[float]:
        _, hy = self.half_extent
        w = (self.tx_width if self.arrangement == "crossing" else self.rx_width) / 2
        out = [-hy, hy, -0.5 * self.rows * self.pitch, 0.5 * self.rows * self.pitch]
        for y in self.y_centers:
            out += [y - w, y + w]
        return out

    def electrode_masks(self, xy: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Which in-plane points lie on each electrode (a tolerance of 1e-9 m on the edges).

        Parameters
        ----------
        xy : (n, 2) float, points of the Tx/Rx planes [m].

        Returns
        -------
        (tx masks, rx masks), lists of (n,) bool in :attr:`electrode_names` order.
        """
        x, y = xy[:, 0], xy[:, 1]
        tol = 1e-9
        xs, ys = self.x_centers, self.y_centers
        wx = 0.5 * self.cols * self.pitch + tol
        wy = 0.5 * self.rows * self.pitch + tol
        rw = self.rx_width / 2 + tol
        if self.arrangement == "pads":
            hx, hy = self.half_extent
            tx = [(np.abs(x) <= hx + tol) & (np.abs(y) <= hy + tol)]
            rx = [(np.abs(x - xs[j]) <= rw) & (np.abs(y - ys[i]) <= rw)
                  for i in range(self.rows) for j in range(self.cols)]
            return tx, rx
        tw = self.tx_width / 2 + tol
        tx = [(np.abs(y - ys[i]) <= tw) & (np.abs(x) <= wx) for i in range(self.rows)]
        rx = [(np.abs(x - xs[j]) <= rw) & (np.abs(y) <= wy) for j in range(self.cols)]
        return tx, rx
