"""Symbolic derivations emitted as C for the estimator (the PX4 way: generated, committed,
checked by a test to be current)."""
