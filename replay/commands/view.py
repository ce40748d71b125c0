"""Open a recording (.rrd), a trial archive or replay results (.mcap) in Rerun, with the workstation's views.

The native viewer needs a display ($DISPLAY or $WAYLAND_DISPLAY); without one,
and without --web, the command prints the command to run elsewhere and exits 0.
--web serves Rerun's web viewer bound to 127.0.0.1 only, the recording fed to it
by URL from a file server on 127.0.0.1 (`replay.views.web`), so the page shows its
loading at once. Of two results archives, the first is run A (as in `compare A B`).

Archives are made into a recording: a trial archive is replayed with
the default methods (those its inputs allow), results archives are re-run
from their input; the recording is `a.rrd` beside `a.mcap`, or `a-vs-b.rrd`
for two. With a viewer to draw in (a display, --web or --connect), a trial
archive is streamed: the viewer opens first and draws each stretch of the mission
as the replay produces it (`replay.views.stream`), the recording saved as it goes,
complete when the replay ends. Without one, and for results archives, the
recording is made whole first (the bulk path), then opened. A file that is already there is never replaced (it may be
someone's earlier recording): the recording takes the next free name (`a-2.rrd`)
and says so; `--save NAME` refuses an existing NAME; `--force` replaces either.
"""

from __future__ import annotations

import argparse
import os
import shlex
from collections.abc import Mapping
from pathlib import Path

from formats.mcap_reader import ArchiveReader
from replay.errors import UserError, warn_damage
from replay.run.config import load_config
from replay.run.outputs import claim_output
from replay.run.pipeline import replay_archive
from replay.run.rebuild import review_from_results, run_metadata

SUFFIXES = (".rrd", ".mcap")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay view`."""
    parser.add_argument("file", nargs="+",
                        help="a Rerun recording (.rrd), a trial archive (.mcap: replayed and shown with every "
                             "view), or one or two replay results archives (two are compared in one recording)")
    parser.add_argument("--web", action="store_true", help="serve the web viewer on 127.0.0.1 instead (it prints "
                                                           "the page to open; the recording is served by URL)")
    parser.add_argument("--connect", metavar="URL",
                        help="stream to a viewer already running (its gRPC URL, rerun+http://HOST:PORT/proxy) "
                             "instead of starting one")
    parser.add_argument("--archive", help="the input trial archive of the results, if not found by itself")
    parser.add_argument("--save", help="with archives: where to save the recording (.rrd); an existing "
                                       "file is refused unless --force")
    parser.add_argument("--force", action="store_true", help="replace an existing recording")
    parser.add_argument("--focus", type=focus_list, default=None, metavar="M1,M2|all",
                        help="the methods shown at first (default: the best of each scoreboard group, the best "
                             "detector, chi_square and anfis; 'all': every method); the others are hidden, one "
                             "click away")


def focus_list(text: str) -> tuple[str, ...]:
    """`--focus a,b,c` as a tuple of method names ('all' for every method); unknown names refused."""
    from replay.stack.methods import METHOD_TABLE

    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n != "all" and n not in METHOD_TABLE]
    if not names or unknown:
        raise argparse.ArgumentTypeError(f"unknown method(s) {', '.join(unknown) or text!r}; known: all, "
                                         + ", ".join(METHOD_TABLE))
    return names


def has_display(env: Mapping[str, str]) -> bool:
    """Whether a native window can open: an X11 or Wayland display is set."""
    return bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))


def check_file(name: str) -> Path:
    """The file to open, or a UserError saying why it cannot be."""
    path = Path(name)
    if path.suffix.lower() not in SUFFIXES:
        raise UserError(f"{name}: expected an .rrd recording or an .mcap archive")
    if not path.is_file():
        raise UserError(f"{name}: no such file")
    return path


def _recording_of_results(args: argparse.Namespace) -> tuple[Path | None, list[str]]:
    """Results archives become one recording (re-run from their inputs); None for a plain file.

    With it, what reading the input archives re-run skipped (one entry per damaged one).
    """
    paths = [check_file(f) for f in args.file]
    metas = [run_metadata(p) if p.suffix.lower() == ".mcap" else None for p in paths]
    if len(paths) == 1 and paths[0].suffix.lower() == ".rrd":
        return None, []
    trial = len(paths) == 1 and metas[0] is None
    if not trial and (any(m is None for m in metas) or len(paths) > 2):
        raise UserError("give one .rrd or .mcap file, or one or two replay results archives")
    from replay.views.recording import save_rrd

    out = recording_path(paths, args.save, args.force)
    print(f"replaying {', '.join(map(str, paths))} into the recording {out}"
          + ("" if args.save else " (--save chooses another file)"), flush=True)
    if trial:     # a trial archive: replayed in memory with what its inputs allow, drawn by our views
        outcome = replay_archive(paths[0], load_config(), write_output=False, review=True, require_work=True)
        reviews = [outcome.review]
    else:
        reviews = [review_from_results(p, args.archive) for p in paths]
    save_rrd(reviews, out, focus=args.focus)
    default = default_recording(paths)
    print(f"saved {out}" + (f" ({default} exists and was kept; --force replaces it)" if out != default and
                            not args.save else ""))
    return out, [r.input_warning for r in reviews if r.input_warning]


def default_recording(paths: list[Path]) -> Path:
    """Where a recording of results archives goes by default: a.rrd, or a-vs-b.rrd for two."""
    if len(paths) == 1:
        return paths[0].with_suffix(".rrd")
    return paths[0].with_name(f"{paths[0].stem}-vs-{paths[1].stem}.rrd")


def recording_path(paths: list[Path], save: str | None, force: bool) -> Path:
    """The file to write: --save (refused when it exists, unless force), else the default or its next free name."""
    if save:
        return claim_output(save, force)
    out = default_recording(paths)
    if force or not (out.exists() or out.is_symlink()):
        return claim_output(out, force)
    k = 2
    while (candidate := out.with_name(f"{out.stem}-{k}{out.suffix}")).exists():
        k += 1
    return candidate


def archive_damage(paths: list[Path]) -> str | None:
    """What reading each .mcap given skips, read through once: Rerun reads archives itself and says nothing."""
    found = []
    for path in paths:
        if path.suffix.lower() != ".mcap":
            continue
        with ArchiveReader(path) as reader:
            for _ in reader.messages():
                pass
            warning = reader.warning()
        if warning:
            found.append(f"{path}: {warning}")
    return "; ".join(found) or None


def _streams(args: argparse.Namespace) -> bool:
    """Whether the file is a trial archive to stream to a viewer: one .mcap without a run, and a viewer to draw in."""
    if len(args.file) != 1 or not (args.web or args.connect or has_display(os.environ)):
        return False
    path = check_file(args.file[0])
    return path.suffix.lower() == ".mcap" and run_metadata(path) is None


def _stream(args: argparse.Namespace) -> int:
    """Open the viewer, replay the trial archive into it stretch by stretch (and into the .rrd), wait for the
    viewer. The damage warning line comes once the recording is complete (the archive read through)."""
    from replay.views.stream import live_viewer, stream_replay

    paths = [check_file(args.file[0])]
    out = recording_path(paths, args.save, args.force)
    with live_viewer(web=args.web, connect=args.connect) as viewer:
        print(f"replaying {paths[0]} into the viewer ({viewer.url}) and the recording {out}"
              + ("" if args.save else " (--save chooses another file)"), flush=True)
        streamed = stream_replay(paths[0], out, viewer.url, load_config(), args.focus)
        default = default_recording(paths)
        first = f"first stretch after {streamed.first_s:.1f} s, " if streamed.first_s is not None else ""
        print(f"saved {out} ({first}{streamed.stretches} stretches)"
              + (f"; {default} exists and was kept (--force replaces it)" if out != default and not args.save
                 else ""), flush=True)
        warn_damage("view", archive_damage(paths))
        return viewer.wait()


def run(args: argparse.Namespace) -> int:
    """Open the file in Rerun and wait for it; print the command instead when there is no display.

    A trial archive with a viewer to draw in is streamed (`_stream`). Otherwise the damage warning line
    comes before the viewer opens (it runs until closed).
    """
    if _streams(args):
        return _stream(args)
    if args.connect:
        raise UserError("--connect streams a trial archive (one .mcap of a trial, not of a replay's results)")
    damage = archive_damage([check_file(f) for f in args.file])
    built, inputs = _recording_of_results(args)
    path = built if built is not None else check_file(args.file[0])
    warn_damage("view", "; ".join(filter(None, [damage, *inputs])) or None)
    from replay.views.recording import open_viewer, viewer_command

    if not args.web and not has_display(os.environ):
        cmd = shlex.join(viewer_command(path))
        print(f"auvreplay view: no display ($DISPLAY / $WAYLAND_DISPLAY unset); on a machine with one, run:\n"
              f"  {cmd}\nor serve the web viewer on 127.0.0.1 with:\n  auvreplay view {shlex.quote(str(path))} --web")
        return 0
    return open_viewer(path, web=args.web)
