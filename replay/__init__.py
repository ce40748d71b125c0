"""The replay engine, the estimator stack, metrics, views and the command line."""
