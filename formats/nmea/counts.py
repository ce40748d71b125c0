"""Every line of an NMEA log counted by sentence address and outcome, so that no sentence goes uncounted.

An epoch's fix counts as one record parsed; the sentences behind it, and
those of the types we do not archive ($GPGSV, $GPGSA, $GPTXT...), are
counted here, per address (talker + type, e.g. 'GPGSV') and outcome:

  used          a GGA, RMC, GLL, GST, VTG, ZDA, HDT or THS read into an epoch
  ignored       a standard NMEA 0183 type we do not archive (GSV, GSA, TXT...)
  unknown       a proprietary sentence ($P...) or a type NMEA 0183 does not define
  bad_checksum  a sentence whose checksum is wrong (of the types the line path verifies)
  rejected      a sentence of ours with fields that cannot be read, or a line with no sentence

Lines without an address are counted under '(no sentence)', '(blank line)'
or '(NovAtel log)'. The counts of a log add up to its lines (a line holding
several sentences glued together counts each of them). At most
MAX_ADDRESSES distinct addresses are kept; further ones (a log of noise)
are counted together under '(other addresses)', so memory stays bounded.
"""

from __future__ import annotations

from collections.abc import Mapping

USED, IGNORED, UNKNOWN, BAD_CHECKSUM, REJECTED = "used", "ignored", "unknown", "bad_checksum", "rejected"
OUTCOMES = (USED, IGNORED, UNKNOWN, BAD_CHECKSUM, REJECTED)
BLANK, NO_SENTENCE, NOVATEL, OTHERS = "(blank line)", "(no sentence)", "(NovAtel log)", "(other addresses)"
MAX_ADDRESSES = 200

# NMEA 0183 v4.10 sentence formatters (the types a talker may send); ours among them
STANDARD = frozenset("""
AAM ABK ABM ACA ACK ACS AIR AKD ALA ALM ALR APB BBM BEC BOD BWC BWR BWW CUR DBK DBS DBT DCN DDC DOR DPT DSC DSE DSI
DSR DTM ETL EVE FIR FSI GBS GEN GFA GGA GLC GLL GMP GNS GRS GSA GST GSV HDG HDM HDT HMR HMS HSC HTC HTD LCD LRF LRI
LR1 LR2 LR3 MLA MSK MSS MTW MWD MWV OSD RMA RMB RMC ROR ROT RPM RSA RSD RTE SFI SSD STN TLB TLL TRC TRD TTD TTM TUT
TXT VBW VDM VDO VDR VHW VLW VPW VSD VTG WAT WCV WNC WPL XDR XTE XTR ZDA ZDL ZFO ZTG THS
""".split())


def skipped_outcome(address: str) -> str:
    """The outcome of a sentence we do not decode: 'ignored' for a standard type, else 'unknown'."""
    return IGNORED if address[:1] != "P" and len(address) == 5 and address[2:] in STANDARD else UNKNOWN


class SentenceCounts:
    """A log's sentences by outcome and address (see the module's docstring), in bounded memory."""

    __slots__ = ("by",)

    def __init__(self) -> None:
        self.by: dict[str, dict[str, int]] = {outcome: {} for outcome in OUTCOMES}

    def add(self, outcome: str, address: str, n: int = 1) -> None:
        """Count `n` sentences of `address` with `outcome`."""
        if n:
            self.merge(outcome, {address: n})

    def merge(self, outcome: str, counts: Mapping[str, int]) -> None:
        """Add per-address counts of one outcome; an address past MAX_ADDRESSES goes under OTHERS."""
        table = self.by[outcome]
        known: set[str] | None = None
        for address, n in counts.items():
            if address not in table:
                if known is None:
                    known = {a for t in self.by.values() for a in t}
                if address not in known and len(known) >= MAX_ADDRESSES:
                    address = OTHERS
                known.add(address)
            table[address] = table.get(address, 0) + n

    def total(self) -> int:
        """Every line (and glued sentence) counted."""
        return sum(sum(t.values()) for t in self.by.values())

    def as_dict(self) -> dict[str, dict[str, int]]:
        """{address: {outcome: count}}, addresses sorted (the archive's recording metadata, key `sentences`)."""
        out: dict[str, dict[str, int]] = {}
        for outcome, table in self.by.items():
            for address, n in table.items():
                if n:
                    out.setdefault(address, {})[outcome] = n
        return dict(sorted(out.items()))


def describe(table: Mapping[str, Mapping[str, int]]) -> str:
    """One line for a log's counts: 'N lines: GPGGA 1700 used, GPGSV 5100 ignored, ...'."""
    total = sum(sum(v.values()) for v in table.values())
    parts = [f"{address} {n} {outcome.replace('_', ' ')}" for address, per in table.items()
             for outcome, n in per.items()]
    return f"{total} lines: " + ", ".join(parts)
