"""Live capture: sensor streams (serial, UDP, TCP, a growing file) into a crash-safe archive as they arrive.

`sources` names the source kinds (one module each), `decoder` feeds a stream
through the same converters `record` uses, `session` runs the selector loop
that archives raw bytes and decoded messages, and `status` keeps the
per-source status line.
"""
