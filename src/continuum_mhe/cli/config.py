"""Options files: ``--config FILE.toml`` holds any option of ``estimate`` and ``live``
(the command line overrides it), and every estimate file records the options it was
made with, as one line a later ``--config`` reads back.

An options file is TOML: each key is an option's long name, with dashes or underscores
(``gap-reset = 2.0``, ``method = "ekf"``, ``skip-bad = true``, ``topic = ["/a", "/b"]``);
an on/off pair is set by its positive name, true or false (``estimate-gyro-bias = false``
for ``--no-estimate-gyro-bias``). Keys at the top apply to every command that takes
``--config``, keys under ``[estimate]`` or ``[live]`` to that command only. An estimate
CSV made by ``estimate`` is an options file too: its ``# options = {...}`` line holds the
options it was made with.
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import os
import re
import sys
from collections.abc import Collection, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from continuum_mhe.cli.program import PROG
from continuum_mhe.errors import InputError
from continuum_mhe.io.robot_file import toml_error_line
from continuum_mhe.io.text_rows import held_text, shorten

if TYPE_CHECKING:
    from continuum_mhe.model.formulations import Formulation

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: the comment line of an estimate CSV that records its options (a TOML line)
OPTIONS_LINE = "options"
#: the comment key of the model an estimate ran on (:func:`model_record`)
MODEL_LINE = "model"
#: the comment key of a robot log's clock at ``t = 0`` (ns since the epoch of its header
#: stamps): an estimate CSV's ``t`` is the time since then
T0_LINE = "t0_ns"
#: options that are never read from a file or recorded: they name files or say how to
#: treat them, not how to estimate
NOT_OPTIONS = frozenset({"help", "config", "overwrite", "output", "record", "func", "command"})
#: options that name a file (relative to where the command runs, else beside the
#: options file: :func:`apply_config`)
FILE_OPTIONS = frozenset({"robot", "inputs"})


def add_config_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--config",
        metavar="FILE.toml",
        help="read options from this TOML file (an estimate CSV's recorded options too); "
        "the command line overrides it",
    )


def _options(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    """The parser's options that a file may set, by destination."""
    return {
        a.dest: a
        for a in parser._actions
        if a.option_strings and not a.required and a.dest not in NOT_OPTIONS
    }


def option_key(action: argparse.Action) -> str:
    """The key of an option in an options file and in an estimate file's record: its
    long name without the dashes; an on/off pair (``--branch-check``,
    ``--no-branch-check``) by its positive name, whose value true or false says which
    of the two was given."""
    if isinstance(action, argparse.BooleanOptionalAction):
        return action.option_strings[0].lstrip("-")
    longs = [s for s in action.option_strings if s.startswith("--")]
    return (longs or action.option_strings)[-1].lstrip("-")


def _by_key(options: dict[str, argparse.Action]) -> dict[str, argparse.Action]:
    """``options`` by :func:`option_key`, with underscores for dashes."""
    return {option_key(a).replace("-", "_"): a for a in options.values()}


def _other_commands_option(command: str, dest: str) -> bool:
    """Whether ``dest`` (underscores for dashes) is an option of the other command that
    an options file serves (``live`` for ``estimate``, and the reverse): a key at the
    file's top applies to both, where it can."""
    other = {"estimate": "live", "live": "estimate"}.get(command)
    if other is None:
        return False
    parser = argparse.ArgumentParser(add_help=False)
    importlib.import_module(f"continuum_mhe.cli.{other}").add_arguments(parser)
    by_key = _by_key(_options(parser))
    return dest in by_key or _negated(dest, by_key) is not None


def _negated(key: str, by_key: dict[str, argparse.Action]) -> argparse.Action | None:
    """The on/off pair whose ``--no-`` spelling ``key`` (underscores for dashes) is,
    else None."""
    if not key.startswith("no_"):
        return None
    action = by_key.get(key[3:])
    return action if isinstance(action, argparse.BooleanOptionalAction) else None


class UnreadableOptions(InputError):
    """An options file, or an estimate file's options line, that is not valid TOML."""


def _read(path: str) -> tuple[dict[str, Any], str, int]:
    """The options of a TOML file or of an estimate CSV's ``# options = {...}`` line, the
    text they were read from (for line numbers) and the file's line number before that
    text's first (0 for a TOML file)."""
    p = Path(path)
    if p.suffix.lower() == ".mcap":  # an estimate MCAP: its options note
        from continuum_mhe.io.mcap_estimates import read_notes_mcap

        if not p.is_file():
            missing = "a folder, not an estimate MCAP" if p.is_dir() else "no such file"
            raise InputError(f"{path}: cannot read the options file ({missing})")
        note = read_notes_mcap(path).get(OPTIONS_LINE)
        if note is None:
            raise InputError(
                f"{path}: no '{OPTIONS_LINE}' note in its continuum-mhe metadata (not an "
                "estimate MCAP, or not readable as MCAP?)"
            )
        text = f"{OPTIONS_LINE} = {note}"
        try:
            recorded = tomllib.loads(text)[OPTIONS_LINE]
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"{path}: its options note: {shorten(str(exc), 200)}") from None
        if not isinstance(recorded, dict):
            raise UnreadableOptions(f"{path}: its options note: {_not_a_table(recorded)}")
        return recorded, text, 0
    held = held_text(path)  # an estimate piped in (read whole, once)
    try:
        text = p.read_text(encoding="utf-8-sig") if held is None else held  # a BOM dropped
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
        raise InputError(f"{path}: cannot read the options file ({why})") from None
    estimate = held is not None or _is_estimate_file(path, text)
    offset = indent = 0
    if estimate:
        found = [
            (n, ln[1:].strip(), len(ln) - len(ln[1:].lstrip()))
            for n, ln in enumerate(text.splitlines())
            if ln.startswith("#") and re.match(rf"{OPTIONS_LINE}\s*=", ln[1:].strip())
        ]
        if not found:
            raise InputError(
                f"{path}: no '# {OPTIONS_LINE} = {{...}}' line (not an estimate file?)"
            )
        offset, text, indent = found[0]
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UnreadableOptions(
            toml_error_line(path, exc, first_line=offset + 1, first_column=indent + 1, text=text)
        ) from None
    except RecursionError:  # arrays or tables nested hundreds deep
        raise InputError(f"{path}: nested too deep to be an options file") from None
    if estimate:
        data = data[OPTIONS_LINE]
        if not isinstance(data, dict):
            raise UnreadableOptions(f"{path}: line {offset + 1}: {_not_a_table(data)}")
    return data, text, offset


def _not_a_table(value: Any) -> str:
    """The problem of an estimate's recorded options that are ``value``, not a table."""
    return (
        f"{OPTIONS_LINE} = {shorten(repr(value), 60)} is not a table of options "
        f"({OPTIONS_LINE} = {{method = ..., ...}})"
    )


def _is_estimate_file(path: str, text: str | None = None) -> bool:
    """Whether the file ``path`` (its ``text``, where read already) is an estimate
    rather than a TOML options file: a ``.csv`` or ``.mcap`` file, one piped in, or one
    that ``estimate`` writes as CSV under another name (``.txt``, no suffix), whose first
    line is its ``# continuum-mhe = ...`` note."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in (".csv", ".mcap") or held_text(path) is not None:
        return True
    if suffix == ".toml":
        return False
    if text is not None:
        first = text.splitlines()[:1]
    else:
        try:
            with p.open(encoding="utf-8-sig") as fh:
                first = [fh.readline()]
        except (OSError, UnicodeDecodeError):
            return False
    return _note_line(first, MADE_LINE) is not None


def _line(text: str, key: str, offset: int = 0) -> str:
    """``line N: `` of ``key``'s first assignment in ``text`` (whose first line is the
    file's line ``offset + 1``), else ``""``."""
    name = rf"""(?:{re.escape(key)}|"{re.escape(key)}"|'{re.escape(key)}')"""  # bare or quoted
    for n, ln in enumerate(text.splitlines(), start=offset + 1):
        if (
            re.match(rf"\s*{name}\s*=", ln)
            or re.search(rf"[{{,]\s*{name}\s*=", ln)
            or re.match(rf"\s*\[+\s*{name}\s*\]", ln)  # a table's header
        ):
            return f"line {n}: "
    return ""


def _value(path: str, where: str, key: str, action: argparse.Action, value: Any) -> Any:
    """``value`` checked against ``action`` and converted as the command line would."""
    flag = "--" + option_key(action)
    switches = (argparse._StoreTrueAction, argparse._StoreFalseAction)
    if isinstance(action, (*switches, argparse.BooleanOptionalAction)):
        if not isinstance(value, bool):
            raise InputError(f"{path}: {where}{key} must be true or false ({flag} is a switch)")
        return not value if isinstance(action, argparse._StoreFalseAction) else value
    if isinstance(action, argparse._AppendAction):
        items = value if isinstance(value, list) else [value]
        return [_one(path, where, key, action, v) for v in items]
    if isinstance(value, (list, dict)):
        raise InputError(f"{path}: {where}{key} takes one value, got {value!r}")
    return _one(path, where, key, action, value)


def _one(path: str, where: str, key: str, action: argparse.Action, value: Any) -> Any:
    convert = action.type if callable(action.type) else None
    if isinstance(value, bool) or isinstance(value, (dict, list)):
        raise InputError(
            f"{path}: {where}{key} = {value!r} is not a value of --{option_key(action)}"
        )
    try:
        converted = convert(str(value)) if convert is not None else str(value)
    except (ValueError, TypeError, argparse.ArgumentTypeError) as exc:
        why = (
            "expected a whole number"
            if convert is int
            else "expected a number"
            if convert is float
            else str(exc)
        )
        raise InputError(f"{path}: {where}{key} = {value!r}: {why}") from None
    if action.choices is not None and converted not in action.choices:
        known = ", ".join(map(str, action.choices))
        raise InputError(f"{path}: {where}{key} = {value!r} is not one of {known}")
    return converted


def apply_config(
    parser: argparse.ArgumentParser, command: str, path: str
) -> tuple[dict[str, str], dict[str, str]]:
    """Set the defaults of ``parser`` (the ``command``'s) from the options file ``path``:
    its top-level keys and those of its ``[command]`` table. A key that is no option of
    the command, or a value the option would refuse, is a one-line error naming the file
    and the line; but an estimate file's options line records the options of the
    command that wrote it (``live``'s port and baud in a live recording's estimate):
    those that are no option of ``command`` are left out, and a note says which. A
    relative robot or tensions file that is not where the command runs but beside the
    options file is taken from there. Returns where each option set was given, by
    destination (``PATH: line N: key = value``), for the checks made later, and the
    table that set it (``"top"``, ``"[command]"``, or ``"recorded"`` for an estimate
    file's options line, which records a run rather than a profile)."""
    data, text, offset = _read(path)
    robot_tables = [k for k in ("section", "imu", "backbone", "tendon") if k in data]
    if robot_tables:  # --config given a robot file
        shown = ", ".join(f"[[{k}]]" if k != "backbone" else "[backbone]" for k in robot_tables)
        first = next(
            (
                f"line {n}: "
                for n, ln in enumerate(text.splitlines(), start=offset + 1)
                if re.match(rf"\s*\[+\s*{robot_tables[0]}\s*\]", ln)
            ),
            "",
        )
        raise InputError(
            f"{path}: {first}{shown}: a robot file, not an options file: give it with --robot"
        )
    options = _options(parser)
    by_key = _by_key(options)
    tables = {"estimate", "live"}
    flat = {k: v for k, v in data.items() if k not in tables}
    for name in tables:  # [estimate] and [live] are tables of options, once each
        if name in data and not isinstance(data[name], dict):
            value = data[name]
            array_of_tables = isinstance(value, list) and all(isinstance(v, dict) for v in value)
            shown = f"[[{name}]]" if array_of_tables and value else f"{name} = ..."
            raise InputError(
                f"{path}: {_line(text, name, offset)}{shown}: the {name} options are one "
                f"table, [{name}]"
            )
    own = data.get(command, {})
    for table in (flat, own):  # gap-reset and gap_reset in one table: which one is meant?
        spelled: dict[str, str] = {}
        for key in table:
            dest = key.replace("-", "_")
            if dest in spelled:
                raise InputError(
                    f"{path}: {_line(text, key, offset)}{key} is given twice, as "
                    f"{spelled[dest]} too ({_line(text, spelled[dest], offset).rstrip(': ')}):"
                    " give it once"
                )
            spelled[dest] = key
    recorded = _is_estimate_file(path)  # an estimate file
    defaults: dict[str, Any] = {}
    sources: dict[str, str] = {}
    set_in: dict[str, str] = {}  # the table that set each destination
    own_keys = set(own)
    left_out: list[str] = []
    files_left_out: list[str] = []
    for key, value in [*flat.items(), *own.items()]:
        dest = key.replace("-", "_")
        where = _line(text, key, offset)
        written = dest == "view" and value not in ("spawn", "web")  # live --view FILE.rrd
        if (dest in NOT_OPTIONS or written) and recorded:  # a file the run that wrote it wrote
            files_left_out.append(key)
            continue
        if dest in NOT_OPTIONS:
            raise InputError(f"{path}: {where}{key} is given on the command line, not in a file")
        action = by_key.get(dest)
        pair = _negated(dest, by_key)
        if action is None and pair is not None and recorded:
            # an estimate file's options line may name an on/off pair by its --no-
            # spelling with the positive switch's value (no-estimate-gyro-bias = false:
            # --no-estimate-gyro-bias was given): the value is the positive key's
            action = pair
        elif action is None and pair is not None:
            given = f"{option_key(pair)} = false for --no-{option_key(pair)}"
            if not isinstance(value, bool) or not value:
                given = f"{option_key(pair)} = true or false"
            raise InputError(
                f"{path}: {where}{key}: an on/off switch is set by its positive name: {given}"
            )
        if action is None and recorded:
            left_out.append(key)
            continue
        if action is None and key not in own_keys and _other_commands_option(command, dest):
            continue  # a key at the top is for both commands: it applies where it can
        if action is None and isinstance(value, dict):
            table = f"{command}.{key}" if key in own_keys else key  # [estimate.noise]
            raise InputError(
                f"{path}: {_line(text, table, offset)}[{table}] is not a table of an options "
                "file ([estimate] and [live] are, besides the options at the top)"
            )
        if action is None:
            near = difflib.get_close_matches(dest, sorted(by_key), n=1, cutoff=0.75)
            hint = f"; did you mean {option_key(by_key[near[0]])}?" if near else ""
            raise InputError(f"{path}: {where}{key} is not an option of {command}{hint}")
        dest = action.dest
        if dest in FILE_OPTIONS and isinstance(value, str):
            value = beside(path, value)
        defaults[dest] = _value(path, where, key, action, value)
        sources[dest] = f"{path}: {where}{key} = {value!r}"
        set_in[dest] = "recorded" if recorded else f"[{command}]" if key in own_keys else "top"
    if left_out:
        print(
            f"{PROG}: note: {path}: {', '.join(left_out)} (of the command that wrote it) "
            f"{'is' if len(left_out) == 1 else 'are'} no option of {command}: left out",
            file=sys.stderr,
        )
    for key in files_left_out:
        print(
            f"{PROG}: note: {path}: {key} names a file of the run that wrote it: left out "
            f"(give --{key} FILE to write one)",
            file=sys.stderr,
        )
    parser.set_defaults(**defaults)
    return sources, set_in


def beside(path: str, value: str) -> str:
    """``value`` (a file named in the options file or estimate ``path``) as a command finds it:
    as given where it exists from the working folder (or is a shipped robot's name),
    else beside the options file where it is there (an absolute name that no longer
    exists: its file name there, as a folder moved with its robot file has it)."""
    given = Path(value)
    there = Path(path).parent / (given.name if given.is_absolute() else given)
    if given.exists() or not there.exists():
        return value
    return str(there)


@dataclass(frozen=True)
class RecordedTensions:
    """Where the tensions an estimate was made with are found here.

    ``written``: the file as the estimate's notes name it; ``path``: that file here;
    ``own_columns``: the recording itself (its tension columns beside the IMUs'), not a
    ``--inputs`` file."""

    written: str
    path: str
    own_columns: bool

    @property
    def how(self) -> str:
        """How the estimate was given them, and which of its lines says so."""
        if self.own_columns:
            return f"from {self.written}'s tension columns, its first line"
        return f"with --inputs {self.written}, its options line"

    def note(self, source: str) -> str:
        """The note that the estimate ``source``'s backbone is drawn with these tensions."""
        if self.own_columns:
            made = f"from {self.written} (its first line): its backbone drawn with that file's"
        else:
            made = f"with --inputs {self.written} (its options line): its backbone drawn with"
        return f"{PROG}: note: {source} was estimated {made} tensions (pass --inputs for others)"


def recorded_tensions(source: str) -> RecordedTensions | None:
    """The tensions the estimate ``source`` was made with, where they are a file here:
    the ``--inputs`` file its options line names, else the recording its
    ``continuum-mhe`` note names (``estimate REC.csv``; ``live``'s ``--record`` file)
    where that has tension columns (``tension_1``...); else None."""
    from continuum_mhe.io.text_rows import open_rows

    name = recorded_option(source, "inputs")
    if isinstance(name, str):
        path = beside(source, name)
        return RecordedTensions(name, path, False) if Path(path).is_file() else None
    name = recorded_recording(source)
    if name is None:
        return None
    path = beside(source, name)
    if not Path(path).is_file():  # (a recording read from a pipe: "-")
        return None
    try:  # its header alone: the reader of the tensions checks them against the robot
        with open_rows(path, "t,...") as rows:
            carries = any(c.startswith("tension_") for c in rows.header)
    except (InputError, OSError):
        return None
    return RecordedTensions(name, path, True) if carries else None


#: the estimate's note of the version and command that made it, and of their input
MADE_LINE = "continuum-mhe"
#: live's words in that note before the name of its --record file
LIVE_RECORDING = "recorded in"


def recorded_recording(source: str) -> str | None:
    """The recording the estimate ``source`` was made from, as its ``continuum-mhe`` note
    names it (``VERSION estimate REC.csv``, ``VERSION live, recorded in RAW.csv``), or
    None (no such note, ``live`` without ``--record``, a file not read)."""
    made = _made_line(source)
    found = (
        None
        if made is None
        else re.fullmatch(rf"\S+ (?:estimate |live, {LIVE_RECORDING} )(.+)", made)
    )
    return None if found is None else found.group(1)


def _note_line(lines: Iterable[str], key: str) -> str | None:
    """The ``key = ...`` note among the ``#`` lines above a CSV's header."""
    for ln in lines:
        if not ln.startswith("#"):
            return None
        if re.match(rf"{key}\s*=", ln[1:].strip()):
            return ln[1:].strip()
    return None


def _note_value(source: str, key: str) -> Any:
    """The value of the estimate ``source``'s note ``key`` (CSV: a ``#`` line above its
    header; MCAP: its notes record), read as TOML, or None."""
    if Path(source).suffix.lower() == ".mcap":
        from continuum_mhe.io.mcap_estimates import read_notes_mcap

        text = read_notes_mcap(source).get(key)
        line = None if text is None else f"{key} = {text}"
    else:
        held = held_text(source)
        try:
            if held is not None:
                line = _note_line(held.splitlines(), key)
            else:
                with Path(source).open(encoding="utf-8-sig") as fh:
                    line = _note_line(fh, key)
        except (OSError, UnicodeDecodeError):
            return None
    if line is None:
        return None
    try:
        return tomllib.loads(line).get(key)
    except tomllib.TOMLDecodeError:
        return None


def _made_line(source: str) -> str | None:
    """The value of the estimate ``source``'s ``continuum-mhe`` note, or None."""
    value = _note_value(source, MADE_LINE)
    return value if isinstance(value, str) else None


def recorded_t0_ns(path: str) -> int | None:
    """An estimate's ``t0_ns`` (its ``# t0_ns = ...`` line, an MCAP's note), ns, or None
    where it has none (not of a robot log) or cannot be read."""
    try:
        value = _note_value(path, T0_LINE)
    except InputError:  # an MCAP whose notes cannot be read: its reader says why
        return None
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def recorded_t0_s(path: str) -> float | None:
    """An estimate's ``t0_ns`` (:func:`recorded_t0_ns`) in s, or None."""
    ns = recorded_t0_ns(path)
    return None if ns is None else ns / 1e9


def recorded_option(path: str, key: str) -> Any:
    """The value of option ``key`` on an estimate CSV's ``# options = {...}`` line (an
    estimate MCAP's ``options`` note), or None where the file has no such line or key
    (or cannot be read: its reader says why)."""
    if Path(path).suffix.lower() == ".mcap":
        from continuum_mhe.io.mcap_estimates import read_notes_mcap

        try:
            options = tomllib.loads(f"o = {read_notes_mcap(path)[OPTIONS_LINE]}")["o"]
        except (KeyError, tomllib.TOMLDecodeError):
            return None
        return options.get(key) if isinstance(options, dict) else None
    try:
        data, _, _ = _read(path)
    except UnreadableOptions as exc:  # an options line that is not valid TOML: said once
        if path not in _UNREAD_OPTIONS:
            _UNREAD_OPTIONS.add(path)
            print(
                f"{PROG}: warning: {exc}: the options the estimate was made with (its robot "
                "file among them) are not read; give them (--robot ...)",
                file=sys.stderr,
            )
        return None
    except InputError:  # no such line, or no such file: its reader says so
        return None
    return data.get(key)


#: The estimate files whose options line could not be read, said once each
_UNREAD_OPTIONS: set[str] = set()


def model_record(formulation: Formulation, branch_check: bool | None = None) -> str:
    """The model an estimate ran on, as the TOML inline table an estimate file records
    beside its options (``{name = "direct", states = ["a_1", ...]}``): the options
    leave some choices to the input (raw IMUs with gyros take the direct model and its
    gyro biases; the MHE's branch check, ``branch_check``, None for a filter), and this
    line says which were made. ``--config`` does not apply it: another input decides
    them again."""
    import json

    names = ", ".join(json.dumps(n) for n in formulation.state_names)
    check = "" if branch_check is None else f", branch-check = {str(branch_check).lower()}"
    return f"{{name = {json.dumps(formulation.name)}, states = [{names}]{check}}}"


def branch_check_ran(estimator: object) -> bool | None:
    """Whether ``estimator`` (of :func:`~continuum_mhe.estimators.make_estimator`) runs
    the MHE's branch check; None where it has no window."""
    inference = getattr(estimator, "inference", None)
    if not hasattr(inference, "branch"):
        return None
    return getattr(inference, "branch", None) is not None


def options_record(
    parser: argparse.ArgumentParser, args: argparse.Namespace, leave_out: Collection[str] = ()
) -> str:
    """The options ``args`` holds, as the TOML inline table an estimate file records
    (``{method = "mhe", horizon = 30, ...}``; options left unset are left out, and so
    are the one-section flags a ``--robot`` file replaces and the destinations
    ``leave_out``: options of another method than the one that ran)."""
    import tomlkit

    table = tomlkit.inline_table()
    # the one-section flags a robot file replaces did not make the estimate
    replaced = getattr(args, "robot_replaces", ()) if getattr(args, "robot", None) else ()
    for dest, action in _options(parser).items():
        value = getattr(args, dest, None)
        if value is None or dest in NOT_OPTIONS or dest in replaced or dest in leave_out:
            continue
        if isinstance(action, argparse._StoreFalseAction):
            value = not value  # recorded as the switch's own sense
        if not isinstance(value, (bool, int, float, str, list)):
            value = str(value)
        if dest in FILE_OPTIONS and isinstance(value, str) and Path(value).exists():
            # the file as any folder finds it (a relative name is the writing run's)
            value = os.path.abspath(value)
        table[option_key(action)] = value
    return table.as_string()
