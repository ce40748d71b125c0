"""Running replays: configuration, the archive-to-results pipeline, metrics, results archives, comparisons, batches."""
