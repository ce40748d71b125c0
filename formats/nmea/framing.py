"""NMEA 0183-style sentence framing ($TTSSS,f1,f2*HH) shared by every ASCII vendor format.

NMEA GPS, PHINS, Micro-Modem, Nortek and others all use this framing; the
vendor modules interpret the fields.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import reduce
from operator import xor

import numpy as np


@dataclass(frozen=True, slots=True)
class Sentence:
    """One framed sentence: address (talker + type, e.g. 'GPGGA'), fields, checksum state."""

    address: str
    fields: list[str]
    has_checksum: bool
    checksum_ok: bool


def nmea_checksum(body: str) -> int:
    """XOR of the characters between '$' (exclusive) and '*' (exclusive)."""
    return reduce(xor, body.encode("latin-1"), 0)


def prefix_xor(data: bytes) -> bytes:
    """prefix[i] = XOR of data[0..i]; the XOR of data[a:b] is prefix[b-1] ^ prefix[a-1]."""
    if not data:
        return b""
    return np.bitwise_xor.accumulate(np.frombuffer(data, dtype=np.uint8)).tobytes()


# two hex digits (either case, mixed too) -> value: a checksum check is one dict lookup
HEX = {f"{i:02X}": i for i in range(256)} | {f"{i:02x}": i for i in range(256)}
HEX |= {f"{i:02X}"[0] + f"{i:02x}"[1]: i for i in range(256)} | {f"{i:02x}"[0] + f"{i:02X}"[1]: i for i in range(256)}


def find_start(text: str, starts: str = "$!") -> int:
    """Index of the first sentence start character in `text` (-1 if none); skips binary noise."""
    best = -1
    for ch in starts:
        i = text.find(ch)
        if i >= 0 and (best < 0 or i < best):
            best = i
    return best


def frame(text: str, starts: str = "$!") -> Sentence | None:
    """Frame one sentence from a line; None when the line holds no sentence start.

    Text before the start character (noise, host prefixes already removed) is
    ignored; a checksum, when present, is verified but the sentence is still
    returned so that the caller can count it as bad.
    """
    i = find_start(text, starts)
    if i < 0:
        return None
    body = text[i + 1 :].rstrip("\r\n ")
    star = body.rfind("*")
    has_checksum = star >= 0 and len(body) - star - 1 >= 2
    checksum_ok = True
    if has_checksum:
        given = body[star + 1 : star + 3]
        payload = body[:star]
        try:
            checksum_ok = int(given, 16) == nmea_checksum(payload)
        except ValueError:
            checksum_ok = False
        body = payload
    parts = body.split(",")
    return Sentence(parts[0], parts[1:], has_checksum, checksum_ok)


def build(address: str, fields: list[str] | tuple[str, ...], start: str = "$") -> str:
    """Encode a sentence with its checksum and CRLF (for simulation and round-trip tests)."""
    payload = ",".join([address, *fields])
    return f"{start}{payload}*{nmea_checksum(payload):02X}\r\n"
