"""The full command line: the parser built from the table of commands
(:data:`continuum_mhe.cli.program.COMMANDS`), and :func:`main`, which runs one command.

User errors (:class:`~continuum_mhe.errors.UserError`, unreadable or unwritable files)
print one line, ``continuum-mhe: error: ...``, and exit with status 2. Anything else is
a bug: one line that says so, with where it happened and where to report it, and exit
status 70 (``CONTINUUM_MHE_TRACEBACK=1`` shows the traceback).
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import re
import signal
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

from continuum_mhe.cli.config import FILE_OPTIONS, apply_config, options_record
from continuum_mhe.cli.method_options import check_robot_replaces
from continuum_mhe.cli.options import check_option_ranges
from continuum_mhe.cli.parser import OneLineParser
from continuum_mhe.cli.program import COMMANDS, DESCRIPTION, PROG, version
from continuum_mhe.cli.program import signal_exit as _signal_exit
from continuum_mhe.errors import InputError, UserError, one_line_warnings
from continuum_mhe.signals import SIGNALS_SEEN as _SIGNALS_SEEN
from continuum_mhe.signals import (
    interrupt_in_chain,
    quiet_unraisable,
)
from continuum_mhe.signals import on_signal as _on_signal


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command in :data:`COMMANDS` (imports each command's module),
    or with ``only`` (a command's name) of that command, the others listed by name and
    help without their options (only its module imported)."""
    parser = OneLineParser(prog=PROG, description=DESCRIPTION)  # errors: one line
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in COMMANDS:
        if only is not None and command.name != only:
            sub.add_parser(command.name, help=command.help)
            continue
        module = importlib.import_module(f"continuum_mhe.cli.{command.module}")
        p = sub.add_parser(
            command.name, help=command.help, description=getattr(module, "DESCRIPTION", None)
        )
        module.add_arguments(p)
        p.set_defaults(func=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; returns its exit status. The one-line warnings, the numpy
    filter, the signal handlers and the unraisable hook it sets last as long as the
    command: a caller (a script, a test) gets its own back."""
    if sys.stderr is None:  # started with stderr closed (2>&-): its lines go nowhere,
        sys.stderr = open(os.devnull, "w")  # noqa: SIM115  # not into stdout's output
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGINT)}
    _SIGNALS_SEEN.clear()  # those of an earlier command run in this process are done
    unraisablehook = sys.unraisablehook
    sys.unraisablehook = quiet_unraisable(unraisablehook)
    try:
        with warnings.catch_warnings(), one_line_warnings(PROG):
            # numerical trouble is flagged in each row's status; numpy's own notes would
            # only surround the summary or the one-line error
            warnings.filterwarnings(
                "ignore",
                r"(invalid value|overflow|divide by zero|underflow) encountered",
                RuntimeWarning,
            )
            try:
                signal.signal(signal.SIGTERM, _on_signal)
                signal.signal(signal.SIGINT, _on_signal)
            except ValueError:  # not the main thread (e.g. called from a test runner's thread)
                pass
            return _run_command(argv)
    finally:
        sys.unraisablehook = unraisablehook
        for sig, handler in handlers.items():
            try:
                signal.signal(sig, handler)
            except (ValueError, TypeError):  # not the main thread; a handler not set from Python
                pass


def _late_positionals(
    command: argparse.ArgumentParser, args: argparse.Namespace, unknown: list[str]
) -> list[str]:
    """``unknown`` less the words that fill the command's optional positionals (``nargs
    "?"``) left empty: argparse gives such a positional its value only next to the ones
    before it, and would leave the truth of ``evaluate EST.csv --json TRUTH.csv`` over."""
    for action in command._actions:
        if not unknown or unknown[0].startswith("-"):
            break
        if not action.option_strings and action.nargs == "?" and getattr(args, action.dest) is None:
            setattr(args, action.dest, unknown.pop(0))
    return unknown


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    # the command word (the top-level options take no value): only its module is imported
    words = sys.argv[1:] if argv is None else argv
    word = next((a for a in words if not a.startswith("-")), None)
    parser = build_parser(only=word)
    args, unknown = parser.parse_known_args(argv)
    (commands,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    command = _given_command(commands.choices[args.command], args)
    unknown = _late_positionals(command, args, unknown)
    if unknown:  # said by the command's parser, so the usage shown is the command's
        command.error(f"unrecognized arguments: {' '.join(unknown)}")
    _refuse_empty_values(command, args)
    on_command_line = _given_options(parser, command, argv)
    sources: dict[str, str] = {}
    tables: dict[str, str] = {}
    config = getattr(args, "config", None)
    if config:  # the file's options, then the command line's again
        appending = {
            a.dest: a.default
            for a in command._actions
            if isinstance(a, argparse._AppendAction) and a.dest in on_command_line
        }
        sources, tables = apply_config(command, args.command, config)
        # an appending option (--topic) on the command line replaces the file's list,
        # as every other option does, instead of adding to it
        command.set_defaults(**appending)
        args, unknown = parser.parse_known_args(argv)
        if _late_positionals(command, args, unknown):  # none: they were said above
            command.error(f"unrecognized arguments: {' '.join(unknown)}")
        for dest, source in sources.items():  # an empty value from the file: as given
            if isinstance(getattr(args, dest, None), str) and not getattr(args, dest).strip():
                raise InputError(f"{source}: an empty value: give one, or leave the key out")
    # where each option that the options file set (and the command line did not) was given
    args.config_sources = {d: w for d, w in sources.items() if d not in on_command_line}
    # ... and in which of the file's tables (a profile's top level, its [command] table,
    # or an estimate file's record of a run)
    args.config_tables = {d: tables[d] for d in args.config_sources}
    # the options given on the command line, which a command refuses where they do not
    # apply (an options file is a profile for several commands and methods: its options
    # apply where they can)
    args.given_options = frozenset(on_command_line)
    if hasattr(args, "config"):
        args.options_parser = command  # the record is written anew once defaults resolve
        args.options_record = options_record(command, args)
    return args


def _given_command(
    command: argparse.ArgumentParser, args: argparse.Namespace
) -> argparse.ArgumentParser:
    """The parser of the subcommand given (``rod tendon``'s), for a command of
    subcommands; else ``command``."""
    while True:
        subs = [a for a in command._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            return command
        command = subs[0].choices[getattr(args, subs[0].dest)]


def _refuse_empty_values(command: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """An error (one line, exit 2) for a value given as an empty string to an argument
    that names a file, a folder or a port (a shell variable left unset): taken as
    given, it would read as the argument left out, or as the current folder."""
    for action in command._actions:
        if action.choices is not None or action.type not in (None, str):
            continue  # (choices and typed values are checked by their own rules)
        value = getattr(args, action.dest, None)
        values = value if isinstance(value, list) else [value]
        if any(isinstance(v, str) and not v.strip() for v in values) and action.default != "":
            name = "/".join(action.option_strings) or str(action.metavar or action.dest)
            command.error(
                f"argument {name}: an empty value (a shell variable left unset?): give one, "
                "or leave the argument out where it may be"
            )


def _given_options(
    parser: argparse.ArgumentParser, command: argparse.ArgumentParser, argv: Sequence[str] | None
) -> set[str]:
    """The destinations of ``command``'s options given on the command line ``argv``: a
    parse with every option's default suppressed, so that only those given are set."""
    actions = [a for a in command._actions if a.option_strings]
    saved = {a: a.default for a in actions}
    saved_defaults = dict(command._defaults)
    try:
        for a in actions:
            a.default = argparse.SUPPRESS
        command._defaults = {
            k: v for k, v in saved_defaults.items() if k not in {a.dest for a in actions}
        }
        namespace, _ = parser.parse_known_args(argv)
    finally:
        for a, default in saved.items():
            a.default = default
        command._defaults = saved_defaults
    return {a.dest for a in actions if hasattr(namespace, a.dest)}


def _from_config(args: argparse.Namespace | None, exc: BaseException) -> str:
    """``PATH: line N: key = value: `` where the user error ``exc`` is about an option
    that the options file (``--config``) set, naming it as the command line's flag
    (``--mount-rpy ...``; not another flag that begins alike, ``--loss-scale`` for
    ``--loss``) or, for a file option, a file it names that is not there (``5: no such
    robot file``); or where the error's fix is another robot (``pass --robot``) and the
    options file set the robot (a recording of another robot's IMUs; not a hint that
    merely names the flag); else ``""``."""
    sources = getattr(args, "config_sources", None)
    if not sources or not isinstance(exc, UserError):
        return ""
    message = str(exc)
    for dest, source in sources.items():
        flag = "--" + dest.replace("_", "-")
        named = re.match(rf"{re.escape(flag)}(?![\w-])", message) is not None
        # the file it names is not there (a file it names that is there and wrong is
        # that file's own error, which names it)
        missing = f"{getattr(args, dest, None)}: no such "
        in_file = dest in FILE_OPTIONS and message.startswith(missing)
        # a robot that the input does not fit: the fix the error names is this setting
        robot = dest == "robot" and re.search(r"pass --robot(?![\w-])", message) is not None
        if named or in_file or robot:
            return f"{source}: "
    return ""


def _run_command(argv: Sequence[str] | None) -> int:
    args: argparse.Namespace | None = None
    try:  # a signal while the parser imports the commands ends the run as one too
        args = _parse(argv)
        if not getattr(args, "own_option_ranges", False):  # (rod's generators: their own)
            check_option_ranges(args)
        check_robot_replaces(args)
        code = int(args.func(args))
    except BaseException as exc:  # noqa: BLE001 - sorted out just below
        if _SIGNALS_SEEN and isinstance(exc, UserError) and interrupt_in_chain(exc) is None:
            # a command that stopped cleanly on the signal and then found a problem with
            # its input (``live``'s end-of-session unit check) says it, as without one
            code = _user_error(exc, _from_config(args, exc))
            return _signal_exit() if signal.SIGTERM in _SIGNALS_SEEN else code
        # a signal raised inside a C extension (CasADi, numpy) can surface as any
        # exception type: once a signal arrived, the run ends as interrupted; a file
        # system's error on the way (the kept rows could not be written) is said too
        if _SIGNALS_SEEN or isinstance(exc, KeyboardInterrupt):
            if isinstance(exc, OSError) and exc.strerror and exc.errno != errno.EINTR:
                _user_error(exc)
            return _signal_exit()
        return _user_error(exc, _from_config(args, exc))
    # a command that drained and finished on its own (``live`` after Ctrl-C) keeps its
    # exit status; after SIGTERM the status is 143, as a service manager expects
    return _signal_exit() if signal.SIGTERM in _SIGNALS_SEEN else code


#: exit status of a bug (sysexits.h EX_SOFTWARE)
EXIT_BUG = 70


def _user_error(exc: BaseException, where: str = "") -> int:
    """One line and exit 2 for user errors (after ``where``: the options file's line that
    set the option, :func:`_from_config`) and file-system errors; anything else is a bug:
    one line saying so (exit 70), the traceback with ``CONTINUUM_MHE_TRACEBACK=1``."""
    if isinstance(exc, UserError):
        print(f"{PROG}: error: {where}{exc}", file=sys.stderr)
        return 2
    if isinstance(exc, BrokenPipeError):  # e.g. `... | head`: the reader left; stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 1
    if isinstance(exc, OSError) and exc.strerror:
        # a stream's error names no file (standard output, an output file's stream)
        where = exc.filename or (
            "writing the output"
            if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
            else "reading or writing a file"
        )
        print(f"{PROG}: error: {where}: {exc.strerror}", file=sys.stderr)
        return 2
    if not isinstance(exc, Exception):  # SystemExit and the like: not ours to report
        raise exc
    return _report_bug(exc)


def _issues_hint() -> str:
    """``at URL`` from the package's ``Project-URL`` metadata, else ``to the maintainers``."""
    from importlib import metadata

    try:
        urls = metadata.metadata("continuum-mhe").get_all("Project-URL") or []
    except metadata.PackageNotFoundError:
        urls = []
    for entry in urls:
        label, _, url = entry.partition(",")
        if label.strip().lower() in ("issues", "bug tracker", "bugs", "tracker"):
            return f"at {url.strip()}"
    return "to the maintainers"


def _report_bug(exc: Exception) -> int:
    """``continuum-mhe: internal error (a bug): TYPE: message (at FILE:LINE)`` and 70."""
    import traceback

    frames = traceback.extract_tb(exc.__traceback__)
    where = f" (at {Path(frames[-1].filename).name}:{frames[-1].lineno})" if frames else ""
    text = str(exc).splitlines()[0] if str(exc) else ""
    if os.environ.get("CONTINUUM_MHE_TRACEBACK"):
        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    print(
        f"{PROG}: internal error (a bug in continuum-mhe): {type(exc).__name__}: {text}"
        f"{where}; please report it with the command {_issues_hint()} "
        "(CONTINUUM_MHE_TRACEBACK=1 shows the traceback)",
        file=sys.stderr,
    )
    return EXIT_BUG


if __name__ == "__main__":
    sys.exit(main())
