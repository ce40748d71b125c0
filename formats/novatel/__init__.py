"""NovAtel OEM logs (BESTPOS, BESTVEL, SPAN INSPVA/INSPVAS/INSPVAX), ASCII and binary.

logs  records, the record-based decoder and the encoders
scan  the hot path: what `logs.decode` yields, as plain tuples
columns  a clean ASCII file's logs as numpy columns (what `scan` yields, for the recording's Batches)
"""
