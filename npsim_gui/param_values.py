"""The parameter panel's names for the chain's parameters: λ1..λ3 address the refinement's
``lambdas`` tuple, ``night.p_<class>`` a per-class activation probability."""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

import numpy as np

from npsim_core.chain import ChainParams

SECTIONS = ("camera", "filter", "uncertainty", "refine", "mesh", "night", "denoise", "lights")


def gui_values(params: ChainParams) -> dict[tuple[str, str], Any]:
    """Flat ``{(section, field): value}`` of everything the parameter panel can show."""
    from npsim_core.chain.stages import light_table

    out: dict[tuple[str, str], Any] = {}
    for sec_name in SECTIONS:
        sec = getattr(params, sec_name)
        for f in fields(sec):
            v = getattr(sec, f.name)
            if isinstance(v, (int, float, str, bool)) or v is None:
                out[(sec_name, f.name)] = v
    out.update({("refine", f"lambda{i + 1}"): params.refine.lambdas[i] for i in range(3)})
    # None means "the optimiser's default": show the value it stands for
    out[("refine", "steps")] = params.refine.n_steps
    out[("refine", "lr")] = params.refine.learning_rate
    table = light_table(replace(params.night, probabilities=()))
    for cid in range(1, 13):
        p = params.night.probability(cid)
        out[("night", f"p_{cid}")] = p if p is not None else float(np.mean(table.spec(cid).p))
    return out


def with_gui_value(params: ChainParams, section: str, name: str, value: Any) -> ChainParams:
    """``params`` with one panel value changed (the panel's names, or any ``section.field``)."""
    if section == "refine" and name in ("lambda1", "lambda2", "lambda3"):
        lam = list(params.refine.lambdas)
        lam[int(name[-1]) - 1] = float(value)
        return params.with_lambdas(*lam)
    if section == "night" and name.startswith("p_"):
        probs = dict(params.night.probabilities)
        probs[int(name[2:])] = float(np.clip(value, 0.0, 1.0))
        return params.with_value("night", "probabilities", tuple(sorted(probs.items())))
    return params.with_value(section, name, value)
