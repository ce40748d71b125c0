"""The push-style replay engine: archive messages in, every method's results out to listeners."""
