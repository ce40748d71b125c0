"""LBL/USBL positioning: KMCDF (seed 003), the delay-only baselines GAR, EAR, LMS, LHC, and their geometry."""
