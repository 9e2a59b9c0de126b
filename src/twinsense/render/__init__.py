"""Ray generation and ray casting shared by every optical/radar sensor."""

from twinsense.render.backends import BACKENDS, backend_available, make_intersector
from twinsense.render.caster import SceneCaster, cast, caster_for
from twinsense.render.hits import Hits
from twinsense.render.rays import OrthographicCamera, PinholeCamera, Rays

__all__ = ["BACKENDS", "Hits", "OrthographicCamera", "PinholeCamera", "Rays", "SceneCaster",
           "backend_available", "cast", "caster_for", "make_intersector"]
