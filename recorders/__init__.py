"""Turning a trial's vendor logs into one archive: one module per sensor family."""
