"""The estimator stack as plain numpy functions: one module per algorithm, no MCAP here."""
