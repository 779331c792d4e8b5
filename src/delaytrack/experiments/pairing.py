"""The paper's comparison as data: AROLC's gains, and which predictor and which tuned gain set
each of the scenarios S1–S4 is compared with. Shared by the paper job and the robustness study."""

from __future__ import annotations

__all__ = ["AROLC_GAINS", "BASELINE", "DELAY_CLASS"]

#: AROLC's gains (the paper's): K1 = K2 = Q = I, α = 2, ε = 0.1, γ = 0.001.
AROLC_GAINS = dict(K1=1.0, K2=1.0, Q=1.0, alpha=2.0, epsilon=0.1, gamma=0.001)
#: The predictor baseline the paper compares with in each scenario.
BASELINE = {"S1": "PCON", "S2": "PCON", "S3": "PCONf", "S4": "PCONf"}
#: The tuning's delay class of each scenario: its gain set for the baselines and AROLC-tuned.
DELAY_CLASS = {"S1": "varying", "S2": "varying", "S3": "constant", "S4": "constant"}
