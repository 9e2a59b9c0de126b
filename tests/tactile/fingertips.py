"""The small crossing skin and the two moving fingertips the frame-solve tests share."""

from __future__ import annotations


def small_skin(**overrides):
    """A 4 x 4 crossing skin (4 mm pitch, 1.5 mm Ecoflex under 0.5 mm PDMS) on a 1 mm mesh, AD7147 readout."""
    from twinsense.capacitive.readout import ReadoutConfig
    from twinsense.capacitive.tactile import StackLayer, StackMeshSettings, TactileConfig, TactileLayout, TactileSensor
    from twinsense.capacitive.tactile.readout import AD7147_READOUT

    lay = TactileLayout("t4", "crossing", 4, 4, 4e-3, 2e-3, 1e-3, dielectric=StackLayer(1.5e-3, 2.8, "ecoflex_0030"),
                        cover=StackLayer(0.5e-3, 2.72, "pdms_sylgard184"), edge=1e-3)
    mesh = StackMeshSettings(h_xy=1e-3, dielectric_cells=2, air_height=0.01, margin=4e-3, h_max=5e-3)
    readout = ReadoutConfig(noise_rms=AD7147_READOUT.noise_rms, resolution=AD7147_READOUT.resolution,
                            sample_rate=30.0)
    return TactileSensor(TactileConfig(lay, mesh, readout, readout, **overrides), name="skin")


def fingertips(k: int, top: float):
    """Two grounded fingertips (R = 6 mm) pressing 0.10-0.15 mm, moving 0.25 mm per frame."""
    from twinsense import Pose, Scene, Sphere

    sc = Scene()
    dx = 0.25e-3 * k
    sc.add_object("index", Sphere(6e-3), "human_skin", pose=Pose((-4e-3 + dx, -4e-3, top + 6e-3 - 0.1e-3)))
    sc.add_object("thumb", Sphere(6e-3), "human_skin",
                  pose=Pose((4e-3 - dx, 4e-3, top + 6e-3 - 0.1e-3 - 0.05e-3 * (k % 2))))
    return sc


def deform_to_third_frame(skin) -> None:
    """Solve the fingertips' first two frames, then deform ``skin`` to the third (contact, displacement,
    the fingertips as objects) without solving it: the state a frame solve starts from."""
    from twinsense.capacitive.coupling import inclusions_from_scene

    top = skin.config.layout.total_thickness
    for k in range(2):
        skin.solve_at(fingertips(k, top), 0.0)
    scene = fingertips(2, top)
    pose = skin.mount.pose_at(scene, 0.0)
    es = skin.electrostatics
    es.set_displacement(skin._contact(scene, 0.0, pose)[0])
    es.set_objects(inclusions_from_scene(scene, 0.0, skin.kind), skin_to_world=pose)


def third_frame_blocks(skin):
    """:func:`deform_to_third_frame`, then that frame's system blocks and warm start:
    (A, K, B, fixed, X_fixed, X0) as the frame solver takes them."""
    from twinsense.capacitive.solver import warm_start
    from twinsense.capacitive.tactile.framesolver import system_blocks

    deform_to_third_frame(skin)
    es = skin.electrostatics
    A, K, B, fixed, X_fixed = system_blocks(es.system)
    return A, K, B, fixed, X_fixed, warm_start(X_fixed, fixed, es.solver.potentials)
