"""Salvage a damaged or cut-off MCAP archive: every intact chunk kept, indexes and summary rebuilt."""

from __future__ import annotations

import argparse
import json
import sys

from formats.mcap_recover import RecoveryReport, recover
from recorders.clock import iso_utc
from replay.run.outputs import claim_output


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay recover`."""
    parser.add_argument("file", help="a damaged MCAP file (any archive, a capture's .part file too)")
    parser.add_argument("-o", "--output", required=True, help="the repaired archive to write")
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    parser.add_argument("--force", action="store_true", help="replace the output if it exists")


def report_json(report: RecoveryReport) -> dict:
    """The `recover --json` object."""
    return {
        "file": report.source, "output": report.output, "size": report.size,
        "chunks_kept": report.chunks_kept, "chunks_lost": report.chunks_lost, "messages": report.messages,
        "attachments": report.attachments, "metadata": report.metadata,
        "orphan_messages": report.orphan_messages, "bytes_lost": report.bytes_lost,
        "start": iso_utc(report.start_ns), "end": iso_utc(report.end_ns),
        "lost": [{"start_byte": r.start, "end_byte": r.end, "reason": r.reason, "chunk": r.chunk,
                  "from": iso_utc(r.start_ns), "to": iso_utc(r.end_ns)} for r in report.lost],
    }


def run(args: argparse.Namespace) -> int:
    """Recover; exit 0 when the output was written (what was lost is reported, not an error)."""
    claim_output(args.output, args.force)  # refused before the (long) scan; the writer claims it again
    report = recover(args.file, args.output, replace=args.force)
    info = report_json(report)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{report.output}: {report.messages} messages in {report.chunks_kept} chunks kept, "
          f"{report.attachments} attachments, {report.metadata} metadata records")
    if not report.lost:
        print("nothing lost")
    for r in info["lost"]:
        span = f", messages {r['from'] or '?'} .. {r['to'] or '?'}" if r["from"] or r["to"] else ""
        what = "chunk" if r["chunk"] else "bytes"
        print(f"lost {what} at bytes {r['start_byte']}..{r['end_byte']} ({r['reason']}){span}", file=sys.stderr)
    if report.orphan_messages:
        print(f"{report.orphan_messages} messages whose channel was defined only in lost bytes: "
              "kept under /recovered/channel-<id>", file=sys.stderr)
    return 0
