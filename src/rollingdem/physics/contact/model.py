"""ContactModel: the contact law, a normal, a tangential, a rolling, a twisting and a cohesion sub-model, and
the layout of their per-pair parameters and per-contact history in the step loop's rows. The engine
built for it lives in ``rollingdem.engine.codegen``."""

from __future__ import annotations

import numpy as np

from rollingdem.physics.records import HISTORY_FRAME
from rollingdem.physics.contact.base import N_COMMON, SubModel, make_submodel


class ContactModel:
    """The contact law: normal + tangential + rolling + twisting + cohesion sub-models.

    Parameters
    ----------
    normal: "hertz" (default), "hooke", "linear", or a sub-model instance / {"model": name, ...}.
    tangential: "history" (default).
    rolling: "none" (default), "cdt", ... (``rollingdem.physics.contact.ROLLING_MODELS``).
    twisting: "none" (default).
    cohesion: "none" (default), "sjkr", "jkr" (``rollingdem.physics.contact.COHESION_MODELS``).

    Particle-particle and particle-wall contacts use the same sub-model functions.
    """

    def __init__(self, normal="hertz", tangential="history", rolling="none", twisting="none", cohesion="none"):
        self.normal = make_submodel("normal", normal)
        self.tangential = make_submodel("tangential", tangential)
        self.rolling = make_submodel("rolling", rolling)
        self.twisting = make_submodel("twisting", twisting)
        self.cohesion = make_submodel("cohesion", cohesion)
        self.cohesion.check_normal(self.normal)

    def check_coarse_graining(self, alpha: float) -> None:
        """Refuse coarse graining by ``alpha`` if a sub-model declares no rule for it."""
        for sub in self.submodels:
            sub.check_coarse_graining(alpha)

    @property
    def submodels(self) -> tuple[SubModel, ...]:
        return (self.normal, self.tangential, self.rolling, self.twisting, self.cohesion)

    # --- layout -----------------------------------------------------------------------------
    def layout(self) -> dict[str, int]:
        """Where each sub-model's declared parameters start in a pair's row (``NORMAL_PARAMS``, ...,
        after the ``N_COMMON`` common ones) and its history in a contact's (``ROLLING_HISTORY``, ...,
        after the stored normal), the rows' lengths (``N_PARAMS``, ``HISTORY_SIZE``), and the history
        column a contact that lasts past touching keeps its reach in (``DETACH_AT``, -1 for none)."""
        out = {}
        params_at = N_COMMON
        history_at = HISTORY_FRAME
        for sub in self.submodels:
            key = sub.slot.upper()
            out[key + "_PARAMS"] = params_at
            out[key + "_HISTORY"] = history_at
            params_at += sub.n_parameters
            history_at += sub.history_size
        out["N_PARAMS"] = params_at
        out["HISTORY_SIZE"] = history_at
        slot = self.cohesion.detach_slot
        out["DETACH_AT"] = -1 if slot is None else out["COHESION_HISTORY"] + self.cohesion.history._fields.index(slot)
        return out

    @property
    def history_size(self) -> int:
        return self.layout()["HISTORY_SIZE"]

    def pair_table(self, pairs) -> np.ndarray:
        """The (n_materials, n_materials, n_params) table of per-pair parameters, of ``pairs[a][b]``,
        the properties of each pair of materials (``MaterialTable.pairs()``: effective moduli and
        coefficients); the scene hands them down, this layer calls nothing above it."""
        nmat = len(pairs)
        table = np.zeros((nmat, nmat, self.layout()["N_PARAMS"]))
        for a in range(nmat):
            for b in range(nmat):
                pair = pairs[a][b]
                row = [pair.effective_youngs_modulus, pair.effective_shear_modulus, pair.friction,
                       pair.rolling_friction, pair.rolling_damping, pair.restitution]
                for sub in self.submodels:
                    row.extend(sub.pair_row(pair))
                table[a, b, :] = row
        return table

    # --- (de)serialisation ----------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {sub.slot: {"model": sub.name, **sub.settings()} for sub in self.submodels}

    @classmethod
    def from_dict(cls, data: dict) -> "ContactModel":
        return cls(**data)

    def describe(self) -> str:
        """The law in words: each slot's model and the settings given, e.g. "normal hertz,
        tangential history, rolling epsd, no twisting, no cohesion"."""
        parts = []
        for sub in self.submodels:
            given = ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}"
                              for k, v in sub.settings().items() if v is not None)
            parts.append(f"no {sub.slot}" if sub.name == "none" else
                         f"{sub.slot} {sub.name}" + (f" ({given})" if given else ""))
        return ", ".join(parts)

    def __repr__(self):
        return (f"ContactModel(normal={self.normal!r}, tangential={self.tangential!r}, "
                f"rolling={self.rolling!r}, twisting={self.twisting!r}, cohesion={self.cohesion!r})")
