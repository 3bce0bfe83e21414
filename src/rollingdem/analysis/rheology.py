"""The local rheology of a dense granular flow, mu(I) and phi(I) (GDR MiDi 2004; da Cruz et al. 2005;
Jop, Forterre & Pouliquen 2006), from a shear run's continuum fields.

The inertial number compares the time a grain takes to fall into a hole under the pressure with the
shear's time: I = gamma_dot d / sqrt(P / rho_s), with d the grains' diameter and rho_s their
material's density. Steady, homogeneous shear gives the friction mu = tau / P and the solid fraction
phi as functions of I alone:

    mu(I)  = mu_s + (mu_2 - mu_s) / (1 + I_0 / I)      (Jop et al. 2006)
    phi(I) = phi_max - a I                              (da Cruz et al. 2005, for I below about 0.3)

``local_rheology`` turns a profile across a shear flow (a ``fields`` measurement's
``NAME_profile.csv``, or ``rollingdem.analysis.fields.profile``) into one (I, mu, phi) point per
node; ``fit_mu_of_i`` and ``fit_phi_of_i`` fit the two laws with the parameters' standard errors."""

from __future__ import annotations

import math

import numpy as np

from rollingdem.errors import ParameterError, check_positive

__all__ = ["inertial_number", "mu_of_i", "fit_mu_of_i", "fit_phi_of_i", "local_rheology", "box_stress"]


def inertial_number(shear_rate, pressure, diameter: float, density: float):
    """I = |gamma_dot| d / sqrt(P / rho_s) (shear rate 1/s, pressure Pa, diameter m, density kg/m^3);
    NaN where the pressure is not positive."""
    check_positive("diameter", diameter, "m")
    check_positive("density", density, "kg/m^3")
    p = np.asarray(pressure, dtype=float)
    root = np.sqrt(np.where(p > 0.0, p, np.nan) / density)
    return np.abs(np.asarray(shear_rate, dtype=float)) * diameter / root


def mu_of_i(inertial, mu_s: float, mu_2: float, i_0: float):
    """Jop, Forterre & Pouliquen's (2006) friction law mu_s + (mu_2 - mu_s) / (1 + I_0 / I)."""
    inertial = np.asarray(inertial, dtype=float)
    return mu_s + (mu_2 - mu_s) / (1.0 + i_0 / inertial)


def _points(inertial, values, what: str) -> tuple[np.ndarray, np.ndarray]:
    i = np.asarray(inertial, dtype=float).ravel()
    v = np.asarray(values, dtype=float).ravel()
    if len(i) != len(v):
        raise ParameterError(f"{what}: {len(i)} inertial numbers and {len(v)} values are not allowed: one value each")
    keep = np.isfinite(i) & np.isfinite(v) & (i > 0.0)
    return i[keep], v[keep]


def fit_mu_of_i(inertial, mu) -> dict:
    """Least-squares fit of ``mu_of_i`` to points (I, mu): {mu_s, mu_2, i_0, their standard errors
    (``mu_s_error``, ...: from the fit's covariance, scaled by the residuals), rms (the residuals' root
    mean square), points}, with mu_2 >= mu_s (points that do not rise give mu_2 = mu_s, their
    level). At least four points with I > 0 and spanning a factor 3 in I are needed (the three
    parameters and the curve's bend)."""
    from scipy.optimize import curve_fit  # deferred: slow to load

    i, m = _points(inertial, mu, "mu(I) fit")
    if len(i) < 4 or i.max() < 3.0 * i.min():
        raise ParameterError(f"mu(I) fit of {len(i)} points over I = {i.min() if len(i) else math.nan:.3g}-"
                             f"{i.max() if len(i) else math.nan:.3g} is not allowed: needs at least 4 points with "
                             "I > 0, spanning a factor 3 in I")
    geometric = float(np.exp(np.mean(np.log(i))))
    start = (float(m.min()), float(np.ptp(m)) + 0.05, geometric)
    try:  # in mu_s and mu_2 - mu_s >= 0: the friction does not fall as the flow gets faster
        (mu_s, rise, i_0), cov = curve_fit(lambda x, a, b, c: mu_of_i(x, a, a + b, c), i, m, p0=start,
                                           bounds=([0.0, 0.0, 1e-9], [10.0, 10.0, 1e3]), maxfev=20000)
    except RuntimeError as err:  # no convergence
        raise ParameterError(f"mu(I) fit of {len(i)} points is not allowed: the fit did not converge ({err})") from None
    if np.all(np.isfinite(cov)):
        errors = np.sqrt(np.maximum([cov[0, 0], cov[0, 0] + cov[1, 1] + 2.0 * cov[0, 1], cov[2, 2]], 0.0))
    else:
        errors = np.full(3, math.nan)
    mu_2 = mu_s + rise
    residuals = m - mu_of_i(i, mu_s, mu_2, i_0)
    return {"mu_s": float(mu_s), "mu_2": float(mu_2), "i_0": float(i_0), "mu_s_error": float(errors[0]),
            "mu_2_error": float(errors[1]), "i_0_error": float(errors[2]),
            "rms": float(np.sqrt(np.mean(residuals ** 2))), "points": int(len(i))}


def fit_phi_of_i(inertial, phi) -> dict:
    """Least-squares line phi = phi_max - a I through points (I, phi): {phi_max, a, their standard
    errors, rms, points}; at least three points."""
    i, f = _points(inertial, phi, "phi(I) fit")
    if len(i) < 3 or np.ptp(i) == 0.0:
        raise ParameterError(f"phi(I) fit of {len(i)} points is not allowed: needs at least 3 points with I > 0 "
                             "at two or more inertial numbers")
    design = np.column_stack([np.ones_like(i), -i])
    (phi_max, a), *_ = np.linalg.lstsq(design, f, rcond=None)
    residuals = f - (phi_max - a * i)
    dof = max(len(i) - 2, 1)
    cov = np.linalg.inv(design.T @ design) * float(residuals @ residuals) / dof
    return {"phi_max": float(phi_max), "a": float(a), "phi_max_error": float(math.sqrt(cov[0, 0])),
            "a_error": float(math.sqrt(cov[1, 1])), "rms": float(np.sqrt(np.mean(residuals ** 2))),
            "points": int(len(i))}


def local_rheology(profile: dict, flow: str, gradient: str, diameter: float, density: float) -> dict:
    """Per node of a ``profile`` along ``gradient`` (a mapping of columns with units, as
    ``rollingdem.analysis.fields.profile`` gives and a ``fields`` measurement writes): the shear
    rate d v_flow / d gradient (central differences, one-sided at the ends), the pressure p = tr(sigma)/3,
    the shear stress |sigma_flow,gradient|, mu = |sigma_fg| / p, I (``inertial_number``) and the
    solid fraction where the profile has it; arrays keyed ``"<gradient> (m)"``, ``shear_rate (1/s)``,
    ``pressure (Pa)``, ``shear_stress (Pa)``, ``mu (1)``, ``inertial_number (1)``, ``solid_fraction (1)``."""
    axes = ("x", "y", "z")
    if flow not in axes or gradient not in axes or flow == gradient:
        raise ParameterError(f"flow = {flow!r}, gradient = {gradient!r} is not allowed: must be two different axes "
                             "of x, y, z")
    position = f"{gradient} (m)"
    if position not in profile:
        raise ParameterError(f"profile along {gradient} is needed: the profile has no column {position!r}")
    z = np.asarray(profile[position], dtype=float)
    v = np.asarray(profile[f"velocity_{flow} (m/s)"], dtype=float)
    pressure = sum(np.asarray(profile[f"stress_{a}{a} (Pa)"], dtype=float) for a in axes) / 3.0
    pair = "".join(sorted((flow, gradient), key=axes.index))  # the profile holds xy, xz, yz
    shear = np.abs(np.asarray(profile[f"stress_{pair} (Pa)"], dtype=float))
    rate = np.gradient(v, z)
    with np.errstate(invalid="ignore", divide="ignore"):
        mu = np.where(pressure > 0.0, shear / pressure, np.nan)
    out = {position: z, "shear_rate (1/s)": rate, "pressure (Pa)": pressure, "shear_stress (Pa)": shear,
           "mu (1)": mu, "inertial_number (1)": inertial_number(rate, pressure, diameter, density)}
    if "solid_fraction (1)" in profile:
        out["solid_fraction (1)"] = np.asarray(profile["solid_fraction (1)"], dtype=float)
    return out


def box_stress(forces, branches, masses, velocities, volume: float, streaming=None):
    """The stress of everything in a box of ``volume`` (m^3), compressive positive (Pa): the contacts'
    virial and the particles' kinetic stress about the ``streaming`` velocities (one row per
    particle; None: at rest),

        sigma = (sum_c f_c (x) b_c + sum_p m_p v'_p (x) v'_p) / V,   v' = v - streaming,

    with f_c the force on a contact's particle i and b_c the branch from its partner (or its wall's
    contact point) to i (``Simulation.contact_forces``). The volume average of Weinhart et al.'s
    (2012) coarse-grained stress over a periodic box, and Lees & Edwards' (1972) pressure tensor."""
    volume = check_positive("volume", volume, "m^3")
    f, b = np.asarray(forces, dtype=float).reshape(-1, 3), np.asarray(branches, dtype=float).reshape(-1, 3)
    v = np.asarray(velocities, dtype=float).reshape(-1, 3)
    if streaming is not None:
        v = v - np.asarray(streaming, dtype=float).reshape(-1, 3)
    m = np.asarray(masses, dtype=float).ravel()
    return (f.T @ b + (m[:, None] * v).T @ v) / volume
