"""Where a wrapper gets the belief's hypotheses from.

The relocalizer publishes its hypotheses in ``info["belief"]["hypotheses"]``
(`filters.localization.belief.Belief`): a list sorted by weight of
``{"weight": float, "mean": [x, y, theta], "cov": 3x3 list, "n_particles": int}``.
"""

from __future__ import annotations


def hypotheses_of(env, info: dict) -> list[dict]:
    """The belief's hypotheses: ``info["belief"]["hypotheses"]`` if the ``info`` carries them, else
    those of ``env.unwrapped.mcl.belief()`` (the belief, never the truth)."""
    published = info.get("belief", {}).get("hypotheses")
    if published is not None:
        return list(published)
    return env.unwrapped.mcl.belief().as_dict()["hypotheses"]
