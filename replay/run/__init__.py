"""Running replays: configuration, the archive-to-results pipeline, metrics, results archives, comparisons, batches.

Also the rebuild of a stored run for review (`replay.run.rebuild`), which re-runs the pipeline.
"""
