"""Reproducing the source papers' tables and figures: paper A's detection table, seed 003's KMCDF curves."""
