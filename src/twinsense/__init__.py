"""twinsense: realistic sensor simulation for robotics digital twins.

ToF cameras, FMCW radars and capacitive sensors simulated from a 3-D scene
with moving objects, down to the raw signal.
"""

from twinsense._version import __version__
from twinsense.depthcam import DepthCamera, DepthCameraConfig
from twinsense.errors import ConfigError, GeometryError, RecordingError, TwinsenseError
from twinsense.io.recording import open_recording
from twinsense.render import OrthographicCamera, PinholeCamera, Rays, cast
from twinsense.scenario import ScenarioError, load_scenario
from twinsense.scene import (
    Box,
    Capsule,
    ConstantVelocity,
    Cylinder,
    Keyframes,
    Material,
    MeshFile,
    Mount,
    Oscillation,
    Plane,
    Pose,
    Scene,
    SceneObject,
    Sphere,
    Static,
    TriangleMesh,
    Waypoints,
    get_material,
    register_material,
)
from twinsense.simulate import SimulationResult, simulate

__all__ = [
    "Box", "Capsule", "ConfigError", "ConstantVelocity", "Cylinder", "DepthCamera", "DepthCameraConfig",
    "GeometryError", "Keyframes", "Material", "MeshFile", "Mount", "OrthographicCamera", "Oscillation",
    "PinholeCamera", "Plane", "Pose", "Rays", "RecordingError", "ScenarioError", "Scene", "SceneObject",
    "SimulationResult", "Sphere", "Static", "TriangleMesh", "TwinsenseError", "Waypoints", "__version__",
    "cast", "get_material", "load_scenario", "open_recording", "register_material", "simulate",
]


def __getattr__(name: str):
    # Sensor classes are imported lazily so that `import twinsense` stays fast
    # and a sensor package's optional dependencies load only when used.
    lazy = {"ToFCamera": "twinsense.tof", "FMCWRadar": "twinsense.radar",
            "CapacitiveSensor": "twinsense.capacitive"}
    if name in lazy:
        import importlib

        return getattr(importlib.import_module(lazy[name]), name)
    raise AttributeError(f"module 'twinsense' has no attribute {name!r}")
