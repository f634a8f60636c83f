"""Wall heat-transfer coefficients from free-convection correlations (``ht`` package).

A thermal volume given ``heat_transfer_coefficient=FreeConvection(...)`` takes
its h from the gas state instead of a constant:

    h = Nu(Pr, Gr) · k / L,   Gr = g β |T - T_wall| L³ ρ² / μ²,   Pr = μ cp / k,

with ρ, μ, cp, k and β = -(∂ρ/∂T)_p / ρ of the volume's fluid at its pressure
and the film temperature (T + T_wall) / 2 (for an ideal gas β = 1/T_film). The
Nusselt correlations are those of Caleb Bell's ``ht`` package for a body of the
given shape in a quiescent fluid: Churchill (1983) for spheres, Churchill &
Chu (1975) for vertical plates, and ``ht``'s default method for horizontal
cylinders (Morgan, 1975) and vertical cylinders (McAdams, Weiss & Saunders). Applied to gas enclosed by a wall of that shape they are
an approximation: the same Ra^(1/4) laminar scaling, and the conduction limit
(Nu = 2 for a sphere) when the gas and the wall have one temperature. Forced
convection by the inflow jet is not included.

The coefficient is frozen over each time step at the state where the step
starts (the gas temperature at the end of the previous step): the wall heat
flow h_n·A·(T_wall - T_{n+1}) stays implicit in the temperature, the
correlation is evaluated once per step instead of at every Newton iteration,
and the scheme stays first-order accurate, like backward Euler itself.
"""
from __future__ import annotations

import numpy as np

#: Standard gravity [m/s^2].
GRAVITY = 9.80665


def _nusselt_functions():
    """Nu(Pr, Gr) of ``ht`` per shape (imported on first use)."""
    from ht.conv_free_immersed import (Nu_horizontal_cylinder, Nu_sphere_Churchill,
                                       Nu_vertical_cylinder, Nu_vertical_plate_Churchill)
    return {"sphere": Nu_sphere_Churchill, "horizontal_cylinder": Nu_horizontal_cylinder,
            "vertical_cylinder": Nu_vertical_cylinder,
            "vertical_plate": Nu_vertical_plate_Churchill}


def _common_shape(*shapes):
    """The shape the given shapes broadcast to; without NumPy's machinery where
    they are equal or scalar (the common cases)."""
    full = set(shapes)
    full.discard(())
    if len(full) <= 1:
        return full.pop() if full else ()
    return np.broadcast_shapes(*shapes)


def _expand(a, shape):
    """``a`` with ``shape`` (a copy where it had to broadcast)."""
    if a.shape == shape:
        return a
    out = np.empty(shape)
    out[...] = a
    return out


SHAPES = ("sphere", "horizontal_cylinder", "vertical_cylinder", "vertical_plate")


class FreeConvection:
    """Free (natural) convection coefficient between a volume's gas and its wall.

    Give it as a volume's ``heat_transfer_coefficient`` (with ``area``); see the
    module docstring for the model and its limits.

    Parameters
    ----------
    shape : {'sphere', 'horizontal_cylinder', 'vertical_cylinder', 'vertical_plate'}
        Which ``ht`` correlation (default 'sphere').
    length : float [m], optional
        Characteristic length L: the diameter of a sphere or horizontal cylinder,
        the height of a vertical cylinder or plate. Default for 'sphere': the
        diameter of the sphere holding the volume's gas volume at t = 0; the
        other shapes need it.
    nusselt : callable, optional
        Your own Nu(Pr, Gr) instead of the shape's correlation.

    Examples
    --------
    >>> import softflow as sf
    >>> tank = sf.Container("tank", sf.air, volume=1e-3, area=0.0484,
    ...                     heat_transfer_coefficient=sf.FreeConvection("sphere"))
    """

    def __deepcopy__(self, memo):
        # a correlation is a value (it never changes once made): copies of a
        # System share it
        return self

    def __init__(self, shape="sphere", length=None, nusselt=None):
        from ..units import to_si
        owner = "FreeConvection"
        if shape not in SHAPES:
            raise ValueError(f"{owner}: shape must be one of {SHAPES}, got {shape!r}")
        if nusselt is not None and not callable(nusselt):
            raise ValueError(f"{owner}: nusselt must be a function Nu(Pr, Gr), got {nusselt!r}")
        self.shape = shape
        self.length = None if length is None else to_si(length, "m", name="length", owner=owner)
        if self.length is not None and not self.length > 0:
            raise ValueError(f"{owner}: length must be > 0 [m], got {self.length}")
        if self.length is None and shape != "sphere":
            raise ValueError(f"{owner}: shape {shape!r} needs its characteristic length "
                             "(length=... [m]); only 'sphere' defaults to the volume's diameter")
        self.nusselt = _nusselt_functions()[shape] if nusselt is None else nusselt

    def characteristic_length(self, volume):
        """L [m]: the given length, or the diameter of a sphere of ``volume`` [m^3]."""
        if self.length is not None:
            return self.length
        return (6.0 * volume / np.pi) ** (1.0 / 3.0)

    def coefficient(self, fluid, p, T, T_wall, length):
        """h [W/(m^2 K)] for arrays of gas pressures p [Pa] and temperatures T [K],
        wall temperatures T_wall [K] and characteristic lengths [m]."""
        # np.broadcast_arrays costs ~10 us a call: only what differs from the common
        # shape is expanded (the fluid's calls are cheapest on equal shapes)
        p, T, T_wall, length = (np.asarray(a, dtype=float) for a in (p, T, T_wall, length))
        shape = _common_shape(p.shape, T.shape, T_wall.shape, length.shape)
        T_f = 0.5 * (T + T_wall)
        p, T_f = _expand(p, shape), _expand(T_f, shape)
        rho = fluid.density(p, T_f)
        beta = -fluid.density_dT(p, T_f) / rho
        mu = fluid.viscosity(p, T_f)
        k = fluid.conductivity(p, T_f)
        Pr = np.asarray(mu * fluid.cp(p, T_f) / k)
        # Gr has every input's shape: (p, T, T_wall) through beta, and length
        Gr = np.asarray(GRAVITY * np.abs(beta * (T - T_wall)) * length ** 3 * (rho / mu) ** 2)
        if Pr.shape != Gr.shape:
            Pr, Gr = np.broadcast_arrays(Pr, Gr)
        # NumPy scalars for the correlation (as before): a Python float's division
        # by zero would raise where NumPy's gives inf
        Nu = np.array([float(self.nusselt(a, b)) for a, b in zip(Pr.ravel(), Gr.ravel())])
        h = Nu.reshape(Gr.shape) * k / length
        return float(h) if h.ndim == 0 else h

    def __repr__(self):
        L = "volume's diameter" if self.length is None else f"{self.length:g} m"
        return f"FreeConvection({self.shape!r}, length={L})"
