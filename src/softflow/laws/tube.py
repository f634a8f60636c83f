"""A gas tube's pressure-drop law, compiled: the blended friction law
(:mod:`.friction`) feeding isothermal pipe flow (:mod:`.gas_pipe`).

The one evaluation of a group of gas tubes with constant viscosity and an
analytic friction correlation (:func:`softflow.components.tubes.gas_pipe_drop`
chooses it): one compiled pass over the group instead of some forty NumPy
operations.
"""
from __future__ import annotations

from . import jit
from .friction import fRe_blended
from .gas_pipe import isothermal_pipe


@jit
def isothermal_drop(kind, lo, hi, pa, mf, pb, re_per_mf, c_mu, eD, a, area, c2):
    """p_a - p_b required by the flow mf through a gas tube (isothermal pipe
    flow, the friction term Phi = c_mu (f Re) mf with Re = |mf| re_per_mf),
    and its partials in p_a, mf, p_b: (dp, d_pa, d_mf, d_pb)."""
    Re = abs(mf) * re_per_mf
    phi, dphi = fRe_blended(kind, Re, eD, a, lo, hi)
    Phi = c_mu * phi * mf
    R, R_pa, R_mf, R_pb, _, R_phi, _ = isothermal_pipe(pa, mf, pb, area, c2, Phi)
    return (pa - pb) - R, 1.0 - R_pa, -(R_mf + R_phi * c_mu * (phi + Re * dphi)), -1.0 - R_pb


@jit
def isothermal_drop_array(kind, lo, hi, pa, mf, pb, re_per_mf, c_mu, eD, a, area, c2,
                          dp, d_pa, d_mf, d_pb):
    for i in range(pa.size):
        dp[i], d_pa[i], d_mf[i], d_pb[i] = isothermal_drop(
            kind, lo, hi, pa[i], mf[i], pb[i], re_per_mf[i], c_mu[i], eD[i], a[i], area[i],
            c2)
