"""Bad input gives errors that name the field, the value and what is allowed."""

from __future__ import annotations

import numpy as np
import pytest
from two_pad import two_pad_config

from twinsense.capacitive import layouts as L
from twinsense.capacitive.coupling import Inclusion
from twinsense.capacitive.fem import ElectrostaticSystem
from twinsense.capacitive.layout_mesh import mesh_layout
from twinsense.capacitive.mesh import MeshSettings, tensor_tet_mesh
from twinsense.capacitive.readout import ReadoutConfig
from twinsense.capacitive.sensor import CapacitiveConfig, make_capacitive
from twinsense.capacitive.solver import SolverConfig
from twinsense.errors import ConfigError, UnknownNameError


def test_empty_layout():
    with pytest.raises(ConfigError, match=r"Layout.electrodes = \(\) is invalid: expected at least one"):
        L.Layout(())


def test_overlapping_electrodes():
    a = L.rectangle("a", -0.01, -0.01, 0.002, 0.01)
    b = L.rectangle("b", 0.0, -0.01, 0.01, 0.01)
    with pytest.raises(
        ConfigError,
        match=r"'b' is invalid: expected an electrode that neither "
        r"overlaps nor touches 'a'",
    ):
        mesh_layout(L.Layout((a, b)), MeshSettings(h_min=2e-3, h_max=5e-3, use_cache=False))


def test_electrode_outside_the_mesh():
    far = L.rectangle("far", 0.5, 0.5, 0.51, 0.51)
    near = L.rectangle("near", -0.01, -0.01, 0.01, 0.01)
    settings = MeshSettings(region=(-0.03, 0.03, -0.03, 0.03, -0.01, 0.03), use_cache=False)
    with pytest.raises(
        ConfigError,
        match=r"electrodes\[1\] = 'far' is invalid: expected an "
        r"electrode inside the mesh region",
    ):
        mesh_layout(L.Layout((near, far)), settings)


@pytest.mark.parametrize("eps", [0.0, -2.0])
def test_zero_or_negative_permittivity(eps):
    with pytest.raises(ConfigError, match=r"Substrate.permittivity = .* expected a finite number > 0"):
        L.Substrate(permittivity=eps)
    with pytest.raises(ConfigError, match=r"ball.permittivity = .* expected a finite relative"):
        Inclusion("ball", lambda p: p[:, 0] > 0, np.zeros((2, 3)), eps)
    mesh = tensor_tet_mesh(np.linspace(0, 1, 3), np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    cells = np.ones(mesh.n_cells)
    cells[3] = eps
    with pytest.raises(
        ConfigError,
        match=r"permittivity = .* expected a finite relative "
        r"permittivity > 0 for every cell",
    ):
        ElectrostaticSystem(mesh, [np.array([0])], permittivity=cells)


def test_bad_settings_name_the_field():
    with pytest.raises(ConfigError, match=r"MeshSettings.h_max = 0.0001 .* >= 0.001 \[m \(>= h_min\)\]"):
        MeshSettings(h_min=1e-3, h_max=1e-4)
    with pytest.raises(UnknownNameError, match=r"outer_boundary = 'far' .* grounded, neumann, open"):
        two_pad_config(outer_boundary="far")
    with pytest.raises(UnknownNameError, match=r"CapacitiveConfig.mode = 'quantum'"):
        two_pad_config(mode="quantum")
    with pytest.raises(ConfigError, match=r"pairs\[0\] = \('p0_0', 'nope'\) .* two different sense"):
        two_pad_config(mode="mutual", pairs=(("p0_0", "nope"),))
    with pytest.raises(ConfigError, match=r"ReadoutConfig.noise_rms = -1e-15"):
        ReadoutConfig(noise_rms=-1e-15)
    with pytest.raises(UnknownNameError, match=r"SolverConfig.preconditioner = 'ilu'"):
        SolverConfig(preconditioner="ilu")
    with pytest.raises(UnknownNameError, match=r"capacitive preset = 'toaster' .* printer-bed"):
        make_capacitive("toaster")
    with pytest.raises(ConfigError, match=r"CapacitiveConfig.layout = 3"):
        CapacitiveConfig(3)
    with pytest.raises(ConfigError, match=r"stripes.pitch = 0.005 .* > 0.01 \[m \(> width\)\]"):
        L.stripes(3, 0.01, 0.1, 0.005)
