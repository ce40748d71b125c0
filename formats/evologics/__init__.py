"""EvoLogics S2C modems and USBL: AT-command notifications.

notifications  records, the record-based decoder and the encoders
scan           the hot path: what `notifications.decode` yields, as plain tuples
"""
