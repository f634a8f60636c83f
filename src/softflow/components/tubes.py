"""Tubes."""
from __future__ import annotations

import numpy as np

from ..constants import pressure_atmospheric
from ..correlations.friction import fRe_blended
from .base import FLUID_PORT, LibraryComponent


class CircularTube(LibraryComponent):
    """Straight circular tube between terminals ``a`` and ``b``.

    Darcy–Weisbach pressure drop with the Darcy friction factor from
    Hagen–Poiseuille (f = 64/Re) for laminar flow and Haaland for turbulent
    flow, blended C1-smoothly between Re_laminar and Re_turbulent:

        p_a - p_b = (f Re) · mu L / (2 rho A D^2) · mdot,   Re = |mdot| D / (mu A)

    where mdot is the mass flow entering at ``a``; for gases rho is taken at the
    mean pressure (p_a + p_b)/2. Mass is conserved: mdot_a + mdot_b = 0.

    Parameters
    ----------
    label : str
    fluid : Fluid
    length : float [m]
    diameter : float [m]
        Inner diameter.
    roughness : float [m], default 1.5e-6
        Absolute wall roughness (drawn tubing).
    Re_laminar, Re_turbulent : float [-], default 2300, 4000
        Bounds of the laminar–turbulent blend.
    """

    terminal_spec = (("a", FLUID_PORT), ("b", FLUID_PORT))
    param_names = ("length", "diameter", "roughness", "Re_laminar", "Re_turbulent")
    # V = [p_a, mf_a, p_b, mf_b]; eq 0: mass balance, eq 1: pressure drop
    jac_pattern = ((0, 1), (0, 3), (1, 0), (1, 1), (1, 2))

    def __init__(self, label, fluid, length, diameter, roughness=1.5e-6,
                 Re_laminar=2300.0, Re_turbulent=4000.0):
        super().__init__(label, fluid=None)
        self.fluid = self._check_fluid(fluid)
        self.length = self._si(length, "m", "length", positive=True)
        self.diameter = self._si(diameter, "m", "diameter", positive=True)
        self.roughness = self._si(roughness, "m", "roughness", nonnegative=True)
        self.Re_laminar = self._si(Re_laminar, "", "Re_laminar", positive=True)
        self.Re_turbulent = self._si(Re_turbulent, "", "Re_turbulent", positive=True)
        if self.Re_turbulent <= self.Re_laminar:
            raise ValueError(f"{self.describe()}: Re_turbulent ({self.Re_turbulent}) must exceed "
                             f"Re_laminar ({self.Re_laminar})")

    def group_key(self):
        # one blend range per group keeps the kernel's correlation call scalar-bounded
        return (type(self), id(self.fluid), self.Re_laminar, self.Re_turbulent)

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        P.area = np.pi * P.diameter ** 2 / 4.0
        P.eD = P.roughness / P.diameter
        P.mu = P.fluid.viscosity(np.full(P.n, pressure_atmospheric))
        P.Re_lo = float(P.Re_laminar[0])
        P.Re_hi = float(P.Re_turbulent[0])
        # Re = |mdot| * re_per_mf ; dp = c_mu/rho * (fRe) * mdot
        P.re_per_mf = P.diameter / (P.mu * P.area)
        P.c_mu = P.mu * P.length / (2.0 * P.area * P.diameter ** 2)
        P.compressible = P.fluid.compressible
        return P

    @classmethod
    def kernel(cls, P, V, S, t, dt, jac):
        pa, mfa, pb, mfb = V[:, 0], V[:, 1], V[:, 2], V[:, 3]
        fl = P.fluid
        if P.compressible:
            pm = 0.5 * (pa + pb)
            rho = fl.density(pm)
        else:
            rho = fl.rho
        Re = np.abs(mfa) * P.re_per_mf
        if Re.max() <= P.Re_lo:   # all laminar: f Re = 64 exactly, skip Haaland
            phi, dphi = 64.0, 0.0
        else:
            phi, dphi = fRe_blended(Re, P.eD, P.Re_lo, P.Re_hi)
        c = P.c_mu / rho
        dp_fric = c * phi * mfa
        F = np.empty((P.n, 2))
        F[:, 0] = mfa + mfb
        F[:, 1] = (pa - pb) - dp_fric
        if not jac:
            return F, None
        J = np.empty((P.n, 5))
        J[:, 0] = 1.0
        J[:, 1] = 1.0
        # d(dp_fric)/dp via rho(pm): c ∝ 1/rho
        if P.compressible:
            g = dp_fric / rho * fl.density_dp(pm) * 0.5
        else:
            g = 0.0
        J[:, 2] = 1.0 + g
        J[:, 3] = -c * (phi + Re * dphi)
        J[:, 4] = -1.0 + g
        return F, J
