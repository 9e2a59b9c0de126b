"""Accuracy of the per-sector scene model for plates off axis and tilted: ``python -m twinsense.inductive.offaxis``.

Compares, for the standard square plate of a preset moved sideways and tilted
in front of the face, the impedance change the per-sector model gives
(:class:`~twinsense.inductive.model.ResponseModel`, the rays of the
sensor) with the thin-sheet reference (:mod:`twinsense.inductive.thin_sheet`),
which integrates the head's field over the plate exactly. Both use the same
head field and the same physics: the model's table is the reference's own
centred discs, so what differs is only the model's geometric rule (a sector
counts as a sector of a disc at its mean hit distance).

Two sheets weight the head's field in the two ways a plate can: a
steel-like magnetic sheet (mu_r 100, its eddy term left out: the weight
``|H_t|^2`` of the magnetic term is also how a thick plate's surface
impedance weights the field) and an aluminium-like conducting sheet
(35 MS/m, mu_r 1: only the eddy term ``|A_t - grad psi|^2``, with the
charges at the plate's rim that make the currents close inside it). The
thickness cancels in the relative error (both sides are linear in it).

Prints the table of docs/inductive.md (section 4).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from twinsense.inductive.config import InductiveConfig
from twinsense.inductive.model import ResponseModel
from twinsense.inductive.thin_sheet import HeadField, disc_delta_z, head_field_for, plate_delta_z

#: (name, sigma [S/m], mu_r) of the two sheets.
SHEETS: tuple[tuple[str, float, float], ...] = (("steel-like", 0.0, 100.0), ("aluminium-like", 3.5e7, 1.0))
OFFSETS = (0.0, 0.25, 0.5, 0.75, 1.0)  # x the face radius
TILTS_DEG = (0.0, 10.0, 20.0, 30.0)
_T = 1e-6  # sheet thickness [m]; cancels in every ratio


@dataclass(frozen=True)
class Case:
    sheet: str
    offset: float  # [m] along x
    tilt_deg: float
    reference: complex  # thin-sheet dZ [ohm per A^2]
    model: complex  # per-sector model dZ [ohm per A^2]

    @property
    def error(self) -> float:
        """|dZ_model - dZ_ref| / |dZ_ref|."""
        return abs(self.model - self.reference) / abs(self.reference)


def plate_hits(points: np.ndarray, centre, tilt: float, side: float) -> np.ndarray:
    """Distance [m] along +z from face points (n, 3) to a square plate (inf: the ray misses it)."""
    u_ax = np.array([np.cos(tilt), 0.0, -np.sin(tilt)])
    n_ax = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    c = np.asarray(centre, float)
    t = ((c - points) @ n_ax) / n_ax[2]
    p = points + t[:, None] * np.array([0.0, 0.0, 1.0])
    u, v = (p - c) @ u_ax, (p - c)[:, 1]
    inside = (np.abs(u) <= 0.5 * side) & (np.abs(v) <= 0.5 * side) & (t > 0)
    return np.where(inside, t, np.inf)


def sheet_model(cfg: InductiveConfig, field: HeadField, sheets=SHEETS, sectors: int | None = None) -> ResponseModel:
    """The per-sector model on a table of the thin-sheet centred discs (the model's own inputs)."""
    spec = cfg.table_spec(materials=tuple(sheets))
    table = np.array([[[disc_delta_z(field, d, a, _T, s, m) for a in spec.radii] for d in spec.distances]
                      for _, s, m in sheets])
    return ResponseModel(spec, table, sectors or cfg.sectors)


def study(cfg: InductiveConfig, distance: float | None = None, offsets=OFFSETS, tilts_deg=TILTS_DEG,
          cells: int = 48, sectors: int | None = None, field: HeadField | None = None) -> list[Case]:
    """Offsets (x the face radius, no tilt) and tilts [deg] (centred) of the standard plate at ``distance``.

    ``distance`` [m] of the plate's centre (default s_n); ``cells`` the reference's plate mesh.
    """
    d = cfg.rated_distance if distance is None else distance
    side = cfg.standard_target_side
    if field is None:
        field = head_field_for(cfg.head, cfg.frequency, cfg.mesh, r_max=1.5 * side, z_max=2.5 * cfg.rated_distance)
    model = sheet_model(cfg, field, sectors=sectors)
    pts = model.face_points()
    poses = [(o * cfg.head.face_radius, 0.0) for o in offsets] + [(0.0, t) for t in tilts_deg if t != 0.0]
    out = []
    for m, (name, sigma, mu_r) in enumerate(SHEETS):
        for x, tilt in poses:
            if d - 0.5 * side * np.sin(np.deg2rad(tilt)) <= 0.0:
                continue  # the tilted plate would reach behind the face: not a pose
            centre = (x, 0.0, d)
            ref = plate_delta_z(field, centre, np.deg2rad(tilt), side, _T, sigma, mu_r, cells)
            dist = plate_hits(pts, centre, np.deg2rad(tilt), side)
            mdl = model.delta_z(np.where(np.isfinite(dist), m, -1), dist)
            out.append(Case(name, x, tilt, ref, mdl))
    return out


def main(argv=None) -> None:
    from twinsense.inductive.presets import inductive_config

    names = (argv if argv is not None else sys.argv[1:]) or ["m18_flush"]
    for name in names:
        cfg = inductive_config(name)
        field = head_field_for(cfg.head, cfg.frequency, cfg.mesh, r_max=1.5 * cfg.standard_target_side,
                               z_max=2.5 * cfg.rated_distance)
        for sectors in (cfg.sectors, 16):
            for f in (0.5, 1.0):
                print(f"{name}, plate at {f:g} s_n, {sectors} sectors: sector model vs thin-sheet reference")
                for c in study(cfg, f * cfg.rated_distance, field=field, sectors=sectors):
                    print(f"  {c.sheet:15s} offset {c.offset / cfg.head.face_radius:4.2f} R  tilt {c.tilt_deg:4.0f}"
                          f"  |dZ| ref {abs(c.reference):.4g}  model/ref {abs(c.model) / abs(c.reference):6.3f}"
                          f"  error {100 * c.error:5.1f} %")


if __name__ == "__main__":
    main()
