"""What bytes mean: vendor log formats, the archive's message schemas, MCAP I/O.

Nothing here imports `recorders` or `replay`.
"""
