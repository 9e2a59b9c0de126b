"""Named capacitive sensor configurations (the sensor and the preset registry build on them).

``printer-bed``: six stripe electrodes (10 mm by 200 mm at 30 mm pitch) on a
1.6 mm FR-4 sheet on a 3-D printer's build plate, the CapSense Fig. 10
set-up in shape (the paper's exact stripe dimensions are not published in
the text we follow; these are of the same order).
``pad-grid``: a 3 by 2 grid of 20 mm pads at 30 mm pitch on FR-4 over a
ground plane, self-capacitance mode.
``interdigital``: one Tx/Rx comb pair (5 fingers, 2 mm wide, 30 mm long,
2 mm gaps) in mutual mode.

Readout noise, from the datasheets of the converters these set-ups use
(``ReadoutConfig(noise_rms=0)`` turns it off):

- self capacitance (``printer-bed``, ``pad-grid``): TI FDC1004 (4-channel
  CDC for grounded sensors, SNOSCY5), 16 effective bits over its +-15 pF
  input range at 100 S/s, i.e. 30 pF / 2**16 = 0.46 fF rms per sample
  (the datasheet's "measurement resolution: 0.5 fF");
- mutual capacitance (``interdigital``): Analog Devices AD7745/AD7746
  (CDC for floating Tx/Rx sensors), 21 effective bits over its +-4 pF input
  range at its slowest update rate, 10 Hz: 8 pF / 2**21 = 3.8 aF rms.

The sensors' frame rate differs from those rates; the noise follows it as
``sqrt(frame rate / datasheet rate)`` (see :mod:`twinsense.capacitive.readout`).
"""

from __future__ import annotations

from twinsense.capacitive import layouts as L
from twinsense.capacitive.config import CapacitiveConfig
from twinsense.capacitive.mesh import MeshSettings
from twinsense.capacitive.readout import ReadoutConfig

__all__ = ["AD7746_READOUT", "FDC1004_READOUT", "PRESETS"]

FDC1004_READOUT = ReadoutConfig(noise_rms=30e-12 / 2**16, noise_rate=100.0)
"""TI FDC1004: 0.46 fF rms at 100 S/s (16 effective bits over 30 pF)."""

AD7746_READOUT = ReadoutConfig(noise_rms=8e-12 / 2**21, noise_rate=10.0)
"""Analog Devices AD7745/AD7746: 3.8 aF rms at 10 Hz (21 effective bits over 8 pF)."""


def _printer_bed() -> CapacitiveConfig:
    layout = L.Layout(
        L.stripes(6, 0.010, 0.200, 0.030),
        L.Substrate(1.6e-3, 4.4, extent=(-0.11, 0.11, -0.11, 0.11)),
        name="printer-bed",
    )
    mesh = MeshSettings(margin=0.02, height=0.06, depth=0.01, h_min=2.5e-3, h_max=0.012, growth=1.35)
    return CapacitiveConfig(layout, mesh, readout=FDC1004_READOUT)


def _pad_grid() -> CapacitiveConfig:
    pads = L.pad_grid(3, 2, 0.020, 0.030)
    layout = L.Layout(
        (*pads, L.backplane("gnd", (-0.06, 0.06, -0.045, 0.045), z=-1.6e-3, role="ground")),
        L.Substrate(1.6e-3, 4.4, extent=(-0.06, 0.06, -0.045, 0.045)),
        name="pad-grid",
    )
    mesh = MeshSettings(margin=0.02, height=0.05, depth=0.01, h_min=2e-3, h_max=0.01)
    return CapacitiveConfig(layout, mesh, readout=FDC1004_READOUT)


def _interdigital() -> CapacitiveConfig:
    tx, rx = L.interdigital(5, 0.002, 0.030, 0.002)
    layout = L.Layout((tx, rx), L.Substrate(1.6e-3, 4.4, extent=(-0.03, 0.03, -0.03, 0.03)), name="interdigital")
    mesh = MeshSettings(margin=0.015, height=0.04, depth=0.01, h_min=1e-3, h_max=0.01)
    return CapacitiveConfig(layout, mesh, mode="mutual", readout=AD7746_READOUT)


PRESETS = {
    "printer-bed": (_printer_bed, "6 stripes on a 3-D printer build plate (CapSense Fig. 10)"),
    "pad-grid": (_pad_grid, "3x2 pads over a ground plane, self-capacitance"),
    "interdigital": (_interdigital, "Tx/Rx interdigital comb, mutual capacitance"),
}
