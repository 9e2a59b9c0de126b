"""Robots in the scene: URDF, xacro and MJCF loading, named installed descriptions, MuJoCo
co-simulation, recorded joint states.

Needs the ``robots`` extra (``pip install twinsense[robots]``): yourdfpy for
URDF, xacro for xacro files, mujoco for MJCF and co-simulation,
example-robot-data for the named robots; reading joint states from MCAP also
needs the ``ros2`` extra. A missing package raises ConfigError naming the
extra when used.
"""

from twinsense.robots.materials import LINK_MATERIAL_RULES, default_material, link_materials
from twinsense.robots.mjcf import load_mjcf, mjcf_tree
from twinsense.robots.mujoco_cosim import MujocoBodyMotion, MujocoCosim
from twinsense.robots.recordings import read_joint_states
from twinsense.robots.registry import ROBOTS, load_robot, robot_names, robot_path
from twinsense.robots.urdf import load_urdf, urdf_tree

__all__ = [
    "LINK_MATERIAL_RULES", "ROBOTS", "MujocoBodyMotion", "MujocoCosim", "default_material", "link_materials",
    "load_mjcf", "load_robot", "load_urdf", "mjcf_tree", "read_joint_states", "robot_names", "robot_path",
    "urdf_tree",
]
