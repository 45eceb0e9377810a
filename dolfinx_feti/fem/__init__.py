"""The FEniCSx side: form helpers, per-subdomain assembly, rigid body modes."""

from .forms import Elasticity, Poisson
from .rigid import rigid_modes
from .subdomain import Subdomain

__all__ = ["Elasticity", "Poisson", "Subdomain", "rigid_modes"]
