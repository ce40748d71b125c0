"""WHOI Micro-Modem 1 and 2: $CA/$CC sentences (ping ranging, time of arrival, data cycle).

sentences  records, the record-based decoder and the encoders
scan       the hot path: what `sentences.decode` yields, as plain tuples
"""
