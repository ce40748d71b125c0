"""NovAtel OEM logs (BESTPOS, BESTVEL, SPAN INSPVA/INSPVAS/INSPVAX), ASCII and binary.

logs  records, the record-based decoder and the encoders
scan  the hot path: what `logs.decode` yields, as plain tuples
"""
