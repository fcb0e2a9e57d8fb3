"""Host tools for the attitude EKF (simulate, replay, record, evaluate, benchmark)."""

__version__ = "0.1.0"
