"""Teledyne RDI PD0: ensembles one at a time, runs of like ensembles as columns, coordinate frames.

ensembles  records, the per-ensemble decoder and the encoder (simulation)
blocks     the columnar fast path: runs of like ensembles as numpy columns
frames     Janus beam transform and bottom track to vehicle velocity, for floats and columns alike
"""
