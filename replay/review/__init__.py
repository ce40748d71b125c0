"""What a reviewer sees of a run as DataFrames: collected while the engine runs, or rebuilt from a results archive."""
