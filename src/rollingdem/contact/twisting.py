"""Twisting resistance sub-models (MODELS.md §4.8; MODELS_CONTACTS.md §4).

Kernel signature (slot "twisting")::

    twisting_moment(hist, k, off, nx, ny, nz, dwx, dwy, dwz, overlap, r_eff,
                    tangential_stiffness, tangential_damping, force_elastic, force_total,
                    dt, p, poff) -> (m_twist, dissipation)

The twisting moment acts as -m_twist n on particle i and +m_twist n on particle j.
"""

from __future__ import annotations

from numba import njit

from .base import SubModel


@njit(cache=True)
def no_twisting(hist, k, off, nx, ny, nz, dwx, dwy, dwz, overlap, r_eff, kt, gamma_t, force_elastic,
                force_total, dt, p, poff):
    """No twisting resistance."""
    return 0.0, 0.0


class NoTwisting(SubModel):
    """No twisting resistance: a sphere spinning about the contact normal keeps spinning."""

    slot = "twisting"
    name = "none"
    kernel = ("rollingdem.contact.twisting", "no_twisting")
