"""Contact sub-models (normal, tangential, rolling, twisting, cohesion) and their composition. Every
registered sub-model class is exported here by its class name: a law added to one of the slot
modules needs no edit of an export list."""

# in slot order, the order in which materials list the properties the laws declare
from rollingdem.physics.contact import normal
from rollingdem.physics.contact import tangential
from rollingdem.physics.contact import rolling
from rollingdem.physics.contact import twisting
from rollingdem.physics.contact import cohesion  # noqa: F401 (defining the classes registers them)
from rollingdem.physics.contact.base import COHESION_MODELS, NORMAL_MODELS, ROLLING_MODELS, TANGENTIAL_MODELS, TWISTING_MODELS, SubModel
from rollingdem.physics.contact.model import ContactModel

SUBMODELS = {cls.__name__: cls for registry in (NORMAL_MODELS, TANGENTIAL_MODELS, ROLLING_MODELS, TWISTING_MODELS,
                                                                 COHESION_MODELS)
             for cls in registry.values()}
globals().update(SUBMODELS)

__all__ = ["SubModel", "ContactModel", "NORMAL_MODELS", "TANGENTIAL_MODELS", "ROLLING_MODELS", "TWISTING_MODELS",
           "COHESION_MODELS", *SUBMODELS]
