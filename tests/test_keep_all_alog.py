"""Every MOOS posting of an alog is kept as a message (`/<v>/moos/<VARIABLE>`) that the `mcap` library decodes.

The alog is written here; its own record count is its posting lines (a line that starts with a time after the
LOGSTART header), and every one is archived as itself or refused with a reason.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import alog
from recorders.manifest import load_manifest
from recorders.record import record
from tests.test_keep_all_mavlink import mcap_library_messages

T0 = 1476237600  # 2016-10-12 02:00:00 UTC

ALOG = f"""%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%
%% LOG FILE:       ./LOG_AUV/LOG_AUV.alog
%% LOGSTART           {T0}.000
%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%%
0.100   DB_UPTIME       MOOSDB_auv    0.1
1.000   NAV_X           uSimMarine    10
1.000   NAV_Y           uSimMarine    20
1.000   NAV_DEPTH       uSimMarine    3.5
1.000   NAV_YAW         uSimMarine    -1.5707963
1.500   IVPHELM_SUMMARY pHelmIvP:bhv_waypt  iter=12,utc_time=1476237601.5
2.000   APPCAST         pMarinePID    [auv] pMarinePID
line two of the appcast
   line three, indented
2.500   DEPLOY          pMarineViewer true
3.000   USM_SPEED       uSimMarine    1.25
3.000   SOUNDER_ALT     iSounder      12.5
"""
POSTINGS = 10  # lines that start with a time: the alog's own record count


def trial(tmp: Path, extra: str = "") -> Path:
    (tmp / "auv.alog").write_text(ALOG)
    (tmp / "trial.toml").write_text(
        '[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "auv"\nrole = "follower"\n'
        f'[[vehicles.logs]]\nformat = "alog"\npath = "auv.alog"\n{extra}\n')
    return tmp / "trial.toml"


def _posting_lines(text: str) -> int:
    """The alog's posting lines: after the LOGSTART, starting with a number."""
    count, started = 0, False
    for line in text.splitlines():
        started = started or line.startswith("%% LOGSTART")
        word = line.split(None, 1)[0] if line.split() else ""
        try:
            float(word)
        except ValueError:
            continue
        count += started
    return count


def test_every_posting_is_archived_with_its_app_and_community(tmp_path):
    out = tmp_path / "a.mcap"
    stats = record(load_manifest(trial(tmp_path, 'community = "shoreside_auv"')), out, workers=1).files[0]
    by = mcap_library_messages(out)
    moos = {k: v for k, v in by.items() if k.startswith("/auv/moos/")}
    archived = sum(len(v) for v in moos.values())
    assert _posting_lines(ALOG) == POSTINGS
    assert archived + stats.skipped == POSTINGS and archived == stats.parsed == POSTINGS
    assert set(moos) == {f"/auv/moos/{v}" for v in ("DB_UPTIME", "NAV_X", "NAV_Y", "NAV_DEPTH", "NAV_YAW",
                                                    "IVPHELM_SUMMARY", "APPCAST", "DEPLOY", "USM_SPEED",
                                                    "SOUNDER_ALT")}
    (name, helm), = moos["/auv/moos/IVPHELM_SUMMARY"]
    assert name == "moos.Posting" and helm == {"value": "iter=12,utc_time=1476237601.5", "source": "pHelmIvP",
                                               "aux": "bhv_waypt", "community": "shoreside_auv"}
    assert moos["/auv/moos/APPCAST"][0][1]["value"] == \
        "[auv] pMarinePID\nline two of the appcast\n   line three, indented"
    assert moos["/auv/moos/SOUNDER_ALT"][0][1]["value"] == 12.5 and moos["/auv/moos/DEPLOY"][0][1]["value"] == "true"
    # NAV_X/NAV_Y without an origin: no position; the reason names the manifest key
    assert any("origin = [lat, lon]" in reason for reason in stats.ignored_reasons)
    # the NAV_* epoch still gives heading and depth (NAV_YAW -pi/2: heading 90)
    (_, nav), = by["/auv/ins"]
    assert nav.heading_deg == pytest.approx(90.0) and nav.depth_m == 3.5


def test_community_defaults_to_the_vehicle(tmp_path):
    out = tmp_path / "a.mcap"
    record(load_manifest(trial(tmp_path, "origin = [45.7, 126.6]")), out, workers=1)
    by = mcap_library_messages(out)
    assert {v["community"] for k, msgs in by.items() if k.startswith("/auv/moos/") for _, v in msgs} == {"auv"}
    assert len(by["/auv/ins"]) == 1 and by["/auv/ins"][0][1].latitude > 45.7  # NAV_Y 20 m north of the origin


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["A_VAR", "NAV_X", "B"]),
                          st.lists(st.text(st.characters(blacklist_characters="\r\n", codec="latin-1"),
                                           max_size=12), min_size=1, max_size=3)), max_size=6))
def test_multi_line_values_join_and_every_posting_line_counts(postings):
    lines = [f"%% LOGSTART {T0}"]
    for k, (var, value_lines) in enumerate(postings):
        lines.append(f"{k}.5 {var} app {value_lines[0]}")
        # a value's next lines start with no number (a line that does is a posting of its own)
        lines += [f"x{rest}" for rest in value_lines[1:]]
    got = [p for p in alog.decode(("\n".join(lines) + "\n").encode("latin-1")) if isinstance(p, alog.Posting)]
    assert [p.variable for p in got] == [var for var, _ in postings]
    for p, (_, value_lines) in zip(got, postings):
        nexts = [f"x{rest}" for rest in value_lines[1:]]
        assert p.text.split("\n")[1:] == nexts
        assert p.text.split("\n")[0] == value_lines[0].strip()
    json.dumps([p.text for p in got])
