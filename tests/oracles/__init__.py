"""Independent implementations used as test oracles (and as honest baselines by bench/), not part of rvdiag."""
