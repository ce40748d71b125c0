"""NMEA 0183: the framing every ASCII vendor format shares, and the GNSS sentences.

framing    ``$TTSSS,f1,f2*HH`` framing, checksums, prefix XOR
fields     field rules (time of day, angles, dates, numbers), per-line and column forms side by side
sentences  GGA, RMC, ZDA, VTG, GST, HDT, THS, GLL records; per-line `scan`/`decode`; encoders
clean      whole-log framing of clean logs as columns
columns    the columnar fast path: every sentence of a clean log as numpy columns
counts     every line of a log counted by sentence address and outcome (used, ignored, unknown, ...)
"""
