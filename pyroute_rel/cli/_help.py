"""Help texts that several commands share."""

from __future__ import annotations

__all__ = ["APF_HELP"]

#: What ``--apf`` means, in every command that takes it.
APF_HELP = (
    "acceptable probability of failure in [0, 1]: an arc (a leg) is forbidden when the failure model's probability "
    "of failure in the conditions met along it, p_f, exceeds apf. It bounds each leg, not the voyage: the voyage "
    "p_f (the chance of at least one failure over the whole voyage, from the time spent in each condition) is "
    "reported, not bounded"
)
