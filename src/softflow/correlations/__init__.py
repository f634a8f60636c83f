"""Pure float/array correlations with derivatives, checked against ``fluids``."""
from .friction import friction_Haaland, friction_laminar, fRe_blended, smoothstep

__all__ = ["friction_Haaland", "friction_laminar", "fRe_blended", "smoothstep"]
