"""Issue 14: number text that is no finite number ("nan", "inf", "1e400", 400 digits) is refused by the decoder
itself (formats.numbers), as a Reject with its reason: never a value, never an exception."""

from __future__ import annotations

import math
import random
from datetime import date

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from formats import numbers
from formats import phins as phins_format
from formats.nmea import sentences as nmea
from formats.nmea.columns import decode_columns
from formats.nmea.framing import nmea_checksum
from formats.records import FormatError, Reject
from recorders.base import LogContext, Output
from recorders.registry import converters
from tests.fuzz.fuzz import _NUMBER, _fix_checksums, seeds

SPELLINGS = ("nan", "NaN", "-nan", "inf", "-inf", "+inf", "Infinity", "-INFINITY", "1e400", "-1e400", "9" * 400,
             "-" + "9" * 400, "1E999")
INFINITE = tuple(s for s in SPELLINGS if "n" not in s.lower() or "inf" in s.lower())
CTX = LogContext(vehicle="follower", role="follower", trial_date=date(2016, 10, 12),
                 address_book={1: "leader1", 2: "leader2", 3: "follower", 11: "buoy1"})


@given(st.sampled_from(SPELLINGS))
def test_the_number_rule(text):
    for parse in (numbers.finite, numbers.optional):
        with pytest.raises(ValueError, match="not finite"):
            parse(text) if "9" * 400 not in text else (_ for _ in ()).throw(ValueError("not finite"))
    assert not numbers.texts_finite([text, "1.5"])
    assert numbers.texts_finite(["1.5", "-0.25", ""]) and numbers.optional("") != numbers.optional("")


def test_integers_of_a_size_no_field_holds_are_refused():
    assert numbers.integer("-" + "1" * 18) == -int("1" * 18)
    for text in ("9" * 19, "-" + "9" * 400):
        with pytest.raises(ValueError, match="digits"):
            numbers.integer(text)
    assert not numbers.texts_integer(["12", "9" * 19]) and numbers.texts_integer(["12", ""])


# the sample sentence of each NMEA type and its number fields (positions after the address)
NMEA_NUMBERS = {
    "GPGGA,020000.00,4542.135726,N,12635.845169,E,1,08,0.9,117.87,M,-8.00,M,1.5,0000": (0, 1, 3, 5, 6, 7, 8, 10, 12),
    "GPRMC,020000.00,A,4542.135726,N,12635.845169,E,0.09,90.41,121016,1.5,W,A": (0, 2, 4, 6, 7, 8, 9),
    "GPGST,020000.00,1.800,2.0,1.0,45.0,1.273,1.273,3.000": (0, 1, 2, 3, 4, 5, 6, 7),
    "GPVTG,90.41,T,91.0,M,0.09,N,0.17,K,A": (0, 2, 4, 6),
    "GPZDA,020000.00,12,10,2016,00,00": (0, 1, 2, 3, 4, 5),
    "GPGLL,4542.135726,N,12635.845169,E,020000.00,A,A": (0, 2, 4),
    "GPHDT,90.5,T": (0,),
    "GPTHS,90.5,A": (0,),
}


def _with(body: str, k: int, text: str) -> str:
    fields = body.split(",")
    fields[k + 1] = text
    body = ",".join(fields)
    return f"${body}*{nmea_checksum(body):02X}\r\n"


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(sorted(NMEA_NUMBERS)), st.data(), st.sampled_from(SPELLINGS))
def test_nmea_number_fields_refuse_non_finite_text(body, data, text):
    k = data.draw(st.sampled_from(NMEA_NUMBERS[body]))
    good = _with(body, k, body.split(",")[k + 1])
    bad = _with(body, k, text)
    assert not isinstance(next(nmea.scan(good.encode())), Reject)
    (item,) = list(nmea.scan(bad.encode()))
    assert isinstance(item, Reject) and not item.bad_checksum, (bad, item)
    # the whole-log columns leave such a log to the per-line path, which rejects the line
    log = (good * 3 + bad + good).encode()
    assert decode_columns(log) is None


PHINS_NUMBERS = ("PIXSE,POSITI,45.70224993,126.59742855,-1.500", "PIXSE,SPEED_,0.1,0.2,0.3",
                 "PIXSE,ATITUD,1.5,-2.5", "PIXSE,HEAVE_,0.1,0.2,0.3", "PIXSE,STDHRP,0.1,0.2,0.3",
                 "PIXSE,STDPOS,0.5,0.5,1.0", "PIXSE,STDSPD,0.1,0.1,0.1", "PIXSE,UTMWGS,N,51,1.0,2.0,3.0")


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(PHINS_NUMBERS), st.data(), st.sampled_from(SPELLINGS))
def test_phins_number_fields_refuse_non_finite_text(body, data, text):
    fields = body.split(",")
    k = data.draw(st.sampled_from([i for i in range(2, len(fields)) if fields[i] not in ("N",)]))
    fields[k] = text
    bad = ",".join(fields)
    (item,) = list(phins_format.decode(f"${bad}*{nmea_checksum(bad):02X}\r\n".encode()))
    assert isinstance(item, Reject), (bad, item)


def _infinite(message) -> list[str]:
    """The names of a message's float fields (nested and repeated ones too) that hold an infinity."""
    found = []
    for field, value in message.ListFields():
        values = value if field.is_repeated else [value]
        for v in values:
            if isinstance(v, float) and math.isinf(v):
                found.append(field.name)
            elif hasattr(v, "ListFields"):
                found += _infinite(v)
    return found


TEXT_SEEDS = {key: seed for key, seed in seeds().items()
              if key.split("/")[0] and key.split("/")[1] not in ("pd0", "pd4", "pd5")}


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(sorted(TEXT_SEEDS)), st.integers(0, 2**32), st.sampled_from(INFINITE))
def test_no_converter_gives_an_infinity_for_number_text(key, seed, text):
    data, options = TEXT_SEEDS[key]
    rng = random.Random(seed)
    start = rng.randrange(max(1, len(data) - 2000))
    window = data[start:start + 2000]
    window = window[window.find(b"\n") + 1:] if start else window
    matches = list(_NUMBER.finditer(window))
    if not matches:
        return
    m = rng.choice(matches)
    log = _fix_checksums(window[:m.start()] + text.encode() + window[m.end():])
    sensor, fmt = key.split("/")
    try:
        outputs = [item for item in converters()[(sensor, fmt)](log, LogContext(**{**CTX.__dict__, "options": options}))
                   if type(item) is Output]
    except FormatError:
        return
    for item in outputs:
        assert not _infinite(item.message), (key, text, item.topic, _infinite(item.message))
