"""Scene model: poses, geometry, motion, materials, objects."""

from twinsense.scene.articulated import (
    ArticulatedBody,
    Joint,
    JointConstantVelocity,
    JointKeyframes,
    JointMotion,
    JointSamples,
    JointSetpoints,
    KinematicTree,
    Link,
    LinkMotion,
    Mimic,
    TreeState,
)
from twinsense.scene.geometry import (
    Box,
    Capsule,
    Cylinder,
    Geometry,
    MeshFile,
    Plane,
    Sphere,
    TriangleMesh,
)
from twinsense.scene.magnet import MAGNET_SHAPES, Magnet
from twinsense.scene.materials import Material, get_material, material_names, register_material
from twinsense.scene.motion import (
    ConstantVelocity,
    Keyframes,
    Motion,
    MotionState,
    Oscillation,
    Static,
    Waypoints,
)
from twinsense.scene.pose import Pose
from twinsense.scene.scene import SENSOR_KINDS, Frame, Mount, Scene, SceneObject

__all__ = [
    "MAGNET_SHAPES", "SENSOR_KINDS", "ArticulatedBody", "Box", "Capsule", "ConstantVelocity", "Cylinder", "Frame",
    "Geometry", "Joint", "JointConstantVelocity", "JointKeyframes", "JointMotion", "JointSamples",
    "JointSetpoints", "Keyframes",
    "KinematicTree", "Link", "LinkMotion", "Magnet", "Material", "MeshFile", "Mimic", "Motion", "MotionState", "Mount",
    "Oscillation", "Plane", "Pose", "Scene", "SceneObject", "Sphere", "Static", "TreeState", "TriangleMesh",
    "Waypoints", "get_material", "material_names", "register_material",
]
