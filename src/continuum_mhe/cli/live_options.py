"""Command-line options of the serial stream and the 3D view (``live`` and ``view``):
the port and its line format, the recording of the raw lines, and the Rerun viewer's
sink."""

from __future__ import annotations

import argparse
from typing import Any

from continuum_mhe.cli.options import add_overwrite_option, given_options
from continuum_mhe.errors import InputError


def add_serial_options(p: argparse.ArgumentParser) -> None:
    """The serial stream of ``live``: port, baud, line format."""
    from continuum_mhe.stream.protocol import LINE_FORMATS

    g = p.add_argument_group("serial stream")
    # not argparse's required: an options file may give it (port = "/dev/ttyACM0")
    g.add_argument(
        "--port",
        help="serial device, e.g. /dev/ttyACM0 or COM3 (required: here or as port in --config)",
    )
    g.add_argument("--baud", type=int, default=115200, help="baud rate (default 115200)")
    g.add_argument(
        "--format",
        choices=LINE_FORMATS,
        default="raw",
        help="line format: raw (t_ms + ax,ay,az,gx,gy,gz per IMU, default) or tilt "
        "(t_ms + roll,pitch per IMU); IMUs in the order of --robot",
    )


def add_recording_options(p: argparse.ArgumentParser) -> None:
    """``--record`` and ``--overwrite`` of ``live``."""
    p.add_argument(
        "--record",
        metavar="RAW.csv",
        help="write every valid sample as received (the raw or tilt CSV that 'estimate' "
        "reads, t in s of the device clock, continued past a device clock restart), row "
        "by row",
    )
    add_overwrite_option(p, "-o, --record or --view FILE.rrd")


def _add_port_options(g: argparse._ActionsContainer) -> None:
    g.add_argument("--web-port", type=int, default=9090, help="web viewer HTTP port (9090)")
    g.add_argument("--grpc-port", type=int, default=9876, help="Rerun server port (9876)")
    g.add_argument(
        "--trail", type=float, default=10.0, help="seconds of tip trail shown (default 10)"
    )
    g.add_argument(
        "--points", type=int, default=16, help="backbone points per section (default 16)"
    )


def add_viewer_options(p: argparse.ArgumentParser) -> None:
    """Where ``view`` sends the 3D view (Rerun): a file, the native viewer, or the web."""
    g = p.add_argument_group("3D view (Rerun)")
    sink = g.add_mutually_exclusive_group()
    sink.add_argument("--save", metavar="OUT.rrd", help="write a Rerun file (open: rerun OUT.rrd)")
    sink.add_argument(
        "--spawn", action="store_true", help="show in Rerun's native viewer (default)"
    )
    sink.add_argument(
        "--serve-web",
        action="store_true",
        help="serve Rerun's web viewer on 127.0.0.1 only (until Ctrl-C)",
    )
    _add_port_options(g)


def add_live_view_option(p: argparse.ArgumentParser) -> None:
    """``live --view [spawn|web|FILE.rrd]``: the 3D view of every estimate as it is made."""
    g = p.add_argument_group("3D view (Rerun)")
    g.add_argument(
        "--view",
        nargs="?",
        const="spawn",
        metavar="spawn|web|FILE.rrd",
        help="3D view of the estimates in Rerun: the native viewer (default), the web "
        "viewer on 127.0.0.1, or a .rrd file",
    )
    g.add_argument(
        "--view-hz",
        type=float,
        default=30.0,
        help="draw at most this many estimates per second of sample time (default 30; "
        "0: every estimate); status changes and gaps are always drawn",
    )
    _add_port_options(g)


def viewer_sink_from_args(args: argparse.Namespace) -> Any:
    """The :class:`~continuum_mhe.viewer.ViewerSink` of ``view`` or ``live --view``."""

    from continuum_mhe.io.output_files import check_output_target
    from continuum_mhe.viewer import ViewerSink, require_rerun

    require_rerun()  # the missing install first: the display is the next thing to fix
    ports = {"web_port": args.web_port, "grpc_port": args.grpc_port}
    overwrite = bool(getattr(args, "overwrite", False))
    choice = getattr(args, "view", None)
    if choice is not None:  # live --view
        option, others = "--view", "--view web or --view FILE.rrd"
        if choice in ("spawn", "web"):
            sink = ViewerSink(choice, **ports)
        else:  # an existing file is kept unless --overwrite, as every output
            sink = ViewerSink("save", check_output_target(choice, overwrite, "--view"), **ports)
    else:
        option, others = "--spawn (the default)", "--serve-web or --save FILE.rrd"
        if args.save:
            target = check_output_target(args.save, overwrite, "--save")
            sink = ViewerSink("save", target, **ports)
        else:
            sink = ViewerSink("web" if args.serve_web else "spawn", **ports)
    refuse_unused_view_options(args, sink.kind)
    if why := sink.display_missing():
        raise InputError(f"{option} needs a display ({why}); use {others}")
    return sink


#: the view options each kind of view leaves unused (``None``: ``live`` without ``--view``)
_UNUSED_VIEW_OPTIONS: dict[str | None, tuple[str, ...]] = {
    None: ("view_hz", "trail", "points", "web_port", "grpc_port"),
    "save": ("web_port", "grpc_port"),
    "spawn": ("web_port",),
    "web": (),
}


def refuse_unused_view_options(args: argparse.Namespace, kind: str | None) -> None:
    """A one-line error where an option given on the command line does nothing with the
    view ``kind`` (``save``, ``spawn``, ``web``; None: ``live`` without ``--view``): it
    would be accepted without a word, and the user would think it took effect."""
    given = given_options(args)
    unused = [f"--{d.replace('_', '-')}" for d in _UNUSED_VIEW_OPTIONS[kind] if d in given]
    if not unused:
        return
    which = " and ".join(unused)
    if kind is None:
        why = "without --view: they are for the 3D view (--view spawn, web or FILE.rrd)"
    elif kind == "save":
        why = "with the view written to a file: the ports are for Rerun's viewers"
    else:
        why = "with Rerun's native viewer: the web port is for its web viewer"
    verb = "does" if len(unused) == 1 else "do"
    raise InputError(f"{which} {verb} nothing {why}")
