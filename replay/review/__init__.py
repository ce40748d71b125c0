"""What a reviewer sees of a run as DataFrames: collected while the engine runs, or rebuilt from a results archive.

The rebuild re-runs the replay, so it lives with the pipeline in `replay.run.rebuild`; this package
imports nothing of `replay.run`.
"""
