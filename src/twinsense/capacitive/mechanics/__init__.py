"""Mechanics of a soft tactile skin: linear elasticity with frictionless unilateral contact.

:mod:`materials` (``ElasticMaterial``, presets, the linear range) ->
:mod:`skin_mesh` (layered box meshes) -> :mod:`elasticity` (P1 stiffness and
strains, the nodal volumetric average) with :mod:`ordering` (nested
dissection for the factorisation) and :mod:`kernels` (back substitution) ->
:class:`ElasticBody` (factorised once, contact compliance of the top
surface) -> :mod:`contact` (active-set solve of the Signorini problem) with
:class:`Indenter` (rigid bodies pressed on the skin). See docs/tactile.md.
"""

from twinsense.capacitive.mechanics.body import ElasticBody
from twinsense.capacitive.mechanics.contact import ContactSolution
from twinsense.capacitive.mechanics.indenter import Indenter
from twinsense.capacitive.mechanics.materials import (
    LINEAR_STRAIN_LIMIT,
    MATERIALS,
    POISSON_MAX,
    ElasticMaterial,
    elastic_material,
)
from twinsense.capacitive.mechanics.skin_mesh import LayeredMesh, box_mesh, skin_mesh

__all__ = [
    "LINEAR_STRAIN_LIMIT",
    "MATERIALS",
    "POISSON_MAX",
    "ContactSolution",
    "ElasticBody",
    "ElasticMaterial",
    "Indenter",
    "LayeredMesh",
    "box_mesh",
    "elastic_material",
    "skin_mesh",
]
