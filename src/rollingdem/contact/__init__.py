"""Contact sub-models (normal, tangential, rolling, twisting) and their composition."""

from .base import ROLLING_MODELS, NORMAL_MODELS, TANGENTIAL_MODELS, TWISTING_MODELS, SubModel
from .normal import Hertz, Hooke, Linear
from .tangential import HistorySpring
from .rolling import CDT, EPSD, EPSD2, EPSD3, SDS, DisplacementDamping, ForceProportional, NoRolling, RRLinear, Viscous
from .twisting import Marshall, NoTwisting, TwistingSDS
from .model import ContactModel

__all__ = ["SubModel", "ContactModel", "Hertz", "Hooke", "Linear", "HistorySpring", "NoRolling", "CDT", "EPSD", "EPSD2", "EPSD3", "RRLinear", "SDS", "DisplacementDamping",
           "ForceProportional", "Viscous",
           "NoTwisting", "Marshall", "TwistingSDS", "NORMAL_MODELS", "TANGENTIAL_MODELS", "ROLLING_MODELS", "TWISTING_MODELS"]
